"""docs/errata.md stays true to the tests it cites."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ERRATA = ROOT / "docs" / "errata.md"
CITATION = re.compile(r"`(tests/[\w/]+\.py)::(test_\w+)`")


def test_every_cited_test_exists():
    text = ERRATA.read_text(encoding="utf-8")
    cited = CITATION.findall(text)
    assert len(cited) >= 10, "the errata cite their tests as `path::test_name`"
    missing = [
        f"{path}::{name}"
        for path, name in cited
        if not (ROOT / path).is_file()
        or not re.search(rf"^def {name}\(", (ROOT / path).read_text(encoding="utf-8"), re.M)
    ]
    assert not missing, f"docs/errata.md cites tests that do not exist: {missing}"


def test_every_numbered_entry_cites_a_test():
    rows = [
        line
        for line in ERRATA.read_text(encoding="utf-8").splitlines()
        if re.match(r"\| \d+ \|", line)
    ]
    assert len(rows) >= 10
    for row in rows:
        assert CITATION.search(row), f"erratum without a test: {row[:60]}"
