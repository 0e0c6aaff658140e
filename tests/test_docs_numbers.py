"""Every measured figure has one source: the README shows none, the hand-written guides put
no result tables in prose (the tables of results are rendered from the dated data files
under docs/data/), every data file says when, on what and by which command it was
measured, and a page says so when the code changed after its data."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(ROOT / "scripts"))

import docs_data  # noqa: E402

PERCENT = re.compile(r"\d ?%")
# a duration as a measurement: "17.2 minutes", "546 s", "49 s of CPU" (not "--budget 10m")
DURATION = re.compile(r"\b\d+(?:\.\d+)? ?(?:s|seconds?|min|minutes?|hours?)\b(?! *=)")
# pages that may hold figures outside the data files, each for its reason
NOT_CHECKED = {
    "results-log.md": "the dated record of past rounds, each figure with its day and code",
    "agents.md": "each command's printed output at a tiny budget, an example of the format",
    "identification.md": "being rewritten by its own issue; its tables move to data there",
}


def prose(text: str) -> str:
    """The text outside fenced code blocks."""
    return re.sub(r"```.*?```", "", text, flags=re.S)


def test_the_readme_shows_no_measured_figure():
    text = prose((ROOT / "README.md").read_text(encoding="utf-8"))
    assert not PERCENT.findall(text), PERCENT.findall(text)
    assert not DURATION.findall(text), DURATION.findall(text)
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 150
    main_job = next(i for i, ln in enumerate(lines, 1) if ln.endswith("python -m agents.check"))
    assert main_job <= 40  # the main job's command on the first screen
    assert (ROOT / "CHANGELOG.md").read_text(encoding="utf-8").startswith("# Changelog")


def test_no_guide_has_a_hand_written_table_of_results():
    """A table row with a percentage in a hand-written page is a result copied by hand: it
    belongs in a data file, rendered by the site's hooks (`<!-- data: ... -->`)."""
    found = {}
    for page in sorted(DOCS.glob("*.md")):
        if page.name in NOT_CHECKED:
            continue
        rows = [
            ln
            for ln in prose(page.read_text(encoding="utf-8")).splitlines()
            if ln.startswith("|") and PERCENT.search(ln)
        ]
        if rows:
            found[page.name] = rows[:3]
    assert not found, found


def test_the_learning_page_renders_its_table_from_the_data_file():
    assert "<!-- data: learning -->" in (DOCS / "learning.md").read_text(encoding="utf-8")
    assert "<!-- data: main job -->" in (DOCS / "index.md").read_text(encoding="utf-8")


def test_every_data_file_is_dated_with_its_machine_and_command():
    agents = json.loads((DOCS / "data" / "agents.json").read_text(encoding="utf-8"))
    for run in agents["runs"]:
        assert run["finished"] and run["command"] and run["machine"]["cores"], run
    robustness = json.loads((DOCS / "data" / "robustness.json").read_text(encoding="utf-8"))
    for run in robustness["runs"]:
        assert run["date"] and run["command"] and run["machine"], run
    for name in ("learning.json", "main-job.json"):
        if (DOCS / "data" / name).exists():
            run = json.loads((DOCS / "data" / name).read_text(encoding="utf-8"))["run"]
            assert run["date"] and run["command"] and run["machine"] and run["commit"], run
    for path in (DOCS / "data").glob("learning-precision-*.json"):
        data = json.loads(path.read_text(encoding="utf-8"))
        assert data["date"] and data["commit"] and data["machine"], path
        assert all(r["command"] for r in data["rows"]), path


def test_the_main_job_s_cost_renders_from_its_run(tmp_path, monkeypatch):
    csv = tmp_path / "results.csv"
    csv.write_text(
        "env_id,agent,success_rate,success_low,success_high,timesteps,train_s,algo,note\n"
        "Lagrange/BeadOnRod-v1,lqr,1.0,0.84,1.0,,,,\n"
        "Lagrange/BeadOnRod-v1,ppo,0.95,0.76,0.99,200704,58.0,ppo,\n"
    )
    monkeypatch.setattr(docs_data, "MAIN_JOB", tmp_path / "main-job.json")
    docs_data.store_main_job(str(csv), 1779.0, "python -m agents.check", "quiet")
    text = docs_data.main_job_section()
    assert "30 minutes" in text and "| Lagrange/BeadOnRod-v1 | ppo | 95% [76%, 99%]" in text
    assert "lqr" not in text  # the baselines are the report's, not the cost's


def test_a_result_older_than_the_code_says_so(monkeypatch):
    monkeypatch.setattr(docs_data, "code_change", lambda: ("c0ffee" * 6 + "c0ff", "2026-11-26"))
    assert "Older than the code" in docs_data.staleness(None, "2026-11-23T11:44:03+00:00")
    assert docs_data.staleness(None, "2026-11-27T00:00:00+00:00") == ""
    monkeypatch.setattr(docs_data, "_is_ancestor", lambda a, c: c == "new")
    assert docs_data.staleness("new", None) == ""
    assert "at commit old" in docs_data.staleness("old", None)


def test_a_stored_learning_run_renders_dated_on_its_page(tmp_path, monkeypatch):
    pytest.importorskip("numpy")
    sys.path.insert(0, str(ROOT))
    from benchmarks.learning import FIELDS

    csv = tmp_path / "results.csv"
    row = dict.fromkeys(FIELDS, "")
    row.update(system="Examples/CartPole-v0", algo="ppo", seed=0, success=1.0, low=0.84,
               high=1.0, n=20, train_s=11.0, trained_steps=30000, to80_s=11.0,
               to80_steps=30000)  # fmt: skip
    csv.write_text(",".join(FIELDS) + "\n" + ",".join(str(row[k]) for k in FIELDS) + "\n")
    monkeypatch.setattr(docs_data, "LEARNING", tmp_path / "learning.json")
    docs_data.store_learning([str(csv)], "python benchmarks/learning.py X", 600.0)
    text = docs_data.learning_section()
    assert "Examples/CartPole-v0" in text and "by `python benchmarks/learning.py X`" in text
    assert re.search(r"Measured \d{4}-\d\d-\d\d at commit", text)
