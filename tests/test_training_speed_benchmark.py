"""benchmarks/training_speed.py: its rate and table, its refusal, and (slow) one real run."""

import pytest

from benchmarks import training_speed


def test_a_runs_rate_is_its_last_evaluations_steps_over_its_seconds(tmp_path):
    (tmp_path / "eval.csv").write_text(
        "timesteps,mean_return,std_return,success_rate,mean_length,wall_s\n"
        "10000,-5,1,0.0,250,4.0\n"
        "30000,-2,1,0.5,250,12.0\n"
    )
    assert training_speed.rate(tmp_path) == 2500.0


def test_the_table_gives_each_trees_median_and_the_ratio():
    results = {
        "Lagrange/BeadOnRod-v1": {"this": [3000.0, 1000.0, 2000.0], "baseline": [500.0, 1000.0]}
    }
    header, _, row = training_speed.table(results, baseline=True).splitlines()
    assert header.count("|") == row.count("|")
    assert [c.strip() for c in row.strip("|").split("|")] == [
        "Lagrange/BeadOnRod-v1", "2,000", "750", "2.67",
    ]  # fmt: skip
    assert training_speed.table(results, baseline=False).splitlines()[2].count("|") == 3


def test_a_baseline_that_is_not_a_checkout_is_refused(tmp_path):
    with pytest.raises(SystemExit):
        training_speed.main(["--baseline", str(tmp_path)])


@pytest.mark.slow
def test_a_short_run_measures_this_trees_rate(tmp_path, capsys):
    training_speed.main(["Lagrange/BeadOnRod-v1", "--seconds", "8", "--out", str(tmp_path)])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("| Lagrange/BeadOnRod-v1 |")
    assert float(last.split("|")[2].replace(",", "")) > 0
