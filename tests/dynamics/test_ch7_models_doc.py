"""docs/models.md is what scripts/gen_models_doc.py makes from the models today."""

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow  # derives all twelve models: ~20 s on two cores
def test_committed_models_page_is_up_to_date(tmp_path):
    spec = importlib.util.spec_from_file_location("gen", ROOT / "scripts" / "gen_models_doc.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    written = gen.generate(tmp_path)
    assert {p.name for p in written} >= {"models.md", "eccentric_disk_slider.png"}
    fresh = (tmp_path / "models.md").read_text(encoding="utf-8")
    committed = (ROOT / "docs" / "models.md").read_text(encoding="utf-8")
    assert fresh == committed, "rerun: python scripts/gen_models_doc.py"
