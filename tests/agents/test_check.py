"""The main job on one environment with a tiny budget: table, findings, files."""

from __future__ import annotations

import pytest

from agents.check import main, run_check


def test_check_writes_the_comparison(tmp_path, capsys):
    rows = run_check(
        ["Lagrange/CrankSlider-v1"], episodes=2, out=tmp_path, timesteps=256, progress=False
    )
    assert [r.agent for r in rows] == ["random", "zero", "heuristic", "lqr", "ppo"]
    out = capsys.readouterr().out
    assert "| Lagrange/CrankSlider-v1 | lqr |" in out and "LQR" in out
    for name in ("results.md", "results.csv", "comparison.png"):
        assert (tmp_path / name).stat().st_size > 0
    report = (tmp_path / "results.md").read_text()
    assert "## Findings" in report and "| environment | agent |" in report
    csv_lines = (tmp_path / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 1 + len(rows)
    # a second run resumes the finished training instead of repeating it
    again = run_check(
        ["Lagrange/CrankSlider-v1"], episodes=2, out=tmp_path, timesteps=256, progress=False
    )
    assert again[-1].stats.returns.tolist() == rows[-1].stats.returns.tolist()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["Lagrange/CrankSlide-v1"], "Did you mean 'Lagrange/CrankSlider-v1'"),
        (["--algo", "a2c"], "unknown algorithm 'a2c'"),
        (["--timesteps", "-1"], "expected a positive integer, got -1"),
    ],
)
def test_cli_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err
