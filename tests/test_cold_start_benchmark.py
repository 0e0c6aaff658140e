"""benchmarks/cold_start.py: its table and ratios, its refusals, and (slow) one real cold start."""

import argparse

import pytest

from benchmarks import cold_start


def _run(total: float, cpu: float) -> dict:
    return {"make": total / 2, "reset": 0.0, "step": total / 2, "total": total, "cpu": cpu,
            "fused": total, "fused_cpu": cpu}  # fmt: skip


def test_the_table_gives_each_trees_medians_and_the_ratio():
    results = {
        ("cart_pole", "fresh", "this"): [_run(2.0, 1.0), _run(4.0, 2.0), _run(3.0, 9.0)],
        ("cart_pole", "fresh", "baseline"): [_run(12.0, 8.0), _run(9.0, 4.0), _run(30.0, 6.0)],
    }
    text = cold_start.table(results, ["this", "baseline"])
    header, _, row = text.splitlines()
    assert header.count("|") == row.count("|")
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[:2] == ["cart_pole", "fresh"]
    assert cells[5:7] == ["3.00", "2.00"]  # this tree's median total and cpu
    assert cells[12:14] == ["12.00", "6.00"]  # the baseline's (after 7 phases of this tree's)
    assert cells[-2:] == ["0.25", "0.33"]  # 3 / 12 and 2 / 6


def test_a_baseline_that_is_not_a_checkout_is_refused(tmp_path):
    with pytest.raises(argparse.ArgumentTypeError, match="not a checkout of this project"):
        cold_start._tree(str(tmp_path))
    with pytest.raises(SystemExit):
        cold_start.main(["--rounds", "0"])


@pytest.mark.slow
def test_a_cold_start_measures_every_phase_from_an_empty_cache(tmp_path):
    m = cold_start.measure(cold_start.ROOT, "cart_pole", tmp_path)
    assert set(cold_start.PHASES) <= set(m)
    assert all(m[k] >= 0.0 for k in cold_start.PHASES)
    assert m["total"] >= m["make"] + m["step"] - 1e-9
    assert any((tmp_path / "cache").glob("cart_pole_*.py"))  # the model was built there
