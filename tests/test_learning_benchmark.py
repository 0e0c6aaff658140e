"""benchmarks/learning.py: which systems it runs by default, and its table."""

import csv
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _benchmark():
    spec = importlib.util.spec_from_file_location("learning", ROOT / "benchmarks/learning.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_default_systems_are_the_built_ins_and_every_examples_env():
    bench = _benchmark()
    systems, skipped = bench.default_systems()
    import envs

    assert systems[: len(envs.ENV_IDS)] == list(envs.ENV_IDS)
    # an example joins by being in examples/: each registered id, named with its module
    assert "examples.furuta:Examples/Furuta-v0" in systems
    assert "examples.cart_pole:Examples/CartPole-v0" in systems
    assert all(":" in s for s in systems[len(envs.ENV_IDS) :])
    assert all(s.startswith("examples.") for s in skipped)


def test_the_table_and_csv_say_what_was_met(tmp_path):
    bench = _benchmark()
    row = {"system": "Examples/Furuta-v0", "algo": "ppo", "seed": 0, "success": 0.9, "n": 20,
           "low": 0.7, "high": 0.97, "to80_s": 95.5, "to80_steps": 20480,
           "trained_steps": 20480, "train_s": 96.0, "lqr_share": "", "note": ""}  # fmt: skip
    missed = {**row, "algo": "sac", "to80_s": "", "to80_steps": ""}
    text = bench.table([row, missed], 600, "# header")
    assert "| ppo | 0 | 90% [70%, 97%] | 96 | 20,480 |" in text
    assert "| sac | 0 | 90% [70%, 97%] | not in 600 s |  |" in text
    bench.write([row, missed], tmp_path, 600, "# header")
    read = list(csv.DictReader(open(tmp_path / "results.csv")))
    assert [r["algo"] for r in read] == ["ppo", "sac"] and (tmp_path / "results.md").exists()


def test_runs_over_several_seeds_get_a_row_each_and_one_across_them(tmp_path):
    bench = _benchmark()
    base = {"system": "Examples/Segway-v0", "algo": "ppo", "n": 20, "low": 0.0, "high": 1.0,
            "trained_steps": 1000, "train_s": 60.0, "lqr_share": "", "note": ""}  # fmt: skip
    rows = [
        {**base, "seed": 0, "success": 0.9, "to80_s": 100.0, "to80_steps": 1000},
        {**base, "seed": 1, "success": 0.7, "to80_s": "", "to80_steps": ""},
        {**base, "seed": 2, "success": 1.0, "to80_s": 40.0, "to80_steps": 500},
    ]
    # 18 + 14 + 20 = 52 of 60 episodes: Wilson's interval [76 %, 93 %]; median of 100, 40 s
    assert "| Examples/Segway-v0 | ppo | 0, 1, 2 | 2 of 3 | 87% [76%, 93%] | 70 |" in (
        bench.table(rows, 600, "# h")
    )
    assert "Across training seeds" not in bench.table(rows[:1], 600, "# h")  # one seed: none
    # runs split over processes: one table from their files, the same as from one run
    bench.write(rows[:2], tmp_path / "a", 600, "# a")
    bench.write(rows[2:], tmp_path / "b", 600, "# b")
    csvs = [str(tmp_path / d / "results.csv") for d in "ab"]
    assert bench.main(["--from", *csvs, "--out", str(tmp_path / "all")]) == 0
    assert bench.read_rows([str(tmp_path / "all" / "results.csv")]) == rows


def test_an_unknown_learner_is_refused(capsys):
    bench = _benchmark()
    with pytest.raises(SystemExit) as info:
        bench.main(["Lagrange/BeadOnRod-v1", "--algos", "ppp"])
    err = capsys.readouterr().err
    assert info.value.code == 2 and "Unknown algorithm 'ppp'. Did you mean 'ppo'" in err
