"""python -m agents.identify: record an excitation on an env, fit it, and hand the result to
gym.make; and docs/identification.md's worked example as written."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

from agents import identify

ARM = "Lagrange/TwoLinkArm-v1"


@pytest.mark.slow  # records, fits and draws the figure: ~7 s
def test_record_then_fit_writes_parameters_that_gym_make_takes(tmp_path, capsys):
    """A noise-free record of a plant off nominal (m2 x 0.5) at the env's 20 Hz is fitted
    to 1 % (the regression is exact up to its quadrature's error, of order (omega h)^4:
    measured 3e-3 at h = 0.05 s, under LQR's fast corrections; 1e-7 at 100 Hz), and the
    results carry everything the report promises."""
    record = tmp_path / "arm.npz"
    assert identify.main([ARM, "--record", str(record), "--plant", "m2=0.5",
                          "--seconds", "8", "--candidates", "2"]) == 0  # fmt: skip
    data = np.load(record)
    assert data["q"].shape == (len(data["t"]), 2) and data["u"].shape[1] == 2
    out = tmp_path / "fit"
    assert identify.main([ARM, "--data", str(record), "--out", str(out), "--friction",
                          "theta2=viscous"]) == 0  # fmt: skip
    written = yaml.safe_load((out / "parameters.yml").read_text())
    params = written["parameters"]
    assert written["friction"]["theta2"]["viscous"] == pytest.approx(0.0, abs=1e-2)
    assert params["m2"] == pytest.approx(0.5, rel=1e-2)
    assert params["m1"] == pytest.approx(1.0, rel=1e-2)
    env = gym.make(ARM, **params)
    assert env.unwrapped.system.parameters["m2"] == pytest.approx(0.5, rel=1e-2)
    report = (out / "report.md").read_text()
    assert "| m2 | 0.5" in report and "95 % interval" in report
    assert (out / "identification.png").stat().st_size > 10_000
    assert "identified in" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        ([ARM], "give one of --record FILE or --data FILE"),
        ([ARM, "--record", "x.npz", "--plant", "m2"], "NAME=VALUE"),
        ([ARM, "--data", "missing.npz", "--out", "o"], "No record at"),
        ([ARM, "--record", "x.npz", "--plant", "m_2=1"], "Did you mean 'm2'"),
        (["Lagrange/TwoLinkArm", "--record", "x.npz"], "Did you mean"),
    ],
)
def test_bad_arguments_end_in_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        identify.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.slow  # records, fits and runs 100 episodes twice: ~20 s
def test_the_worked_example_runs_as_written(tmp_path, monkeypatch, capsys):
    page = Path(__file__).resolve().parents[2] / "docs" / "identification.md"
    text = page.read_text(encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for command in block.replace("\\\n", " ").splitlines():
            words = command.split("#")[0].split()
            if not words:
                continue
            assert words[:3] == ["python", "-m", words[2]] and words[2].startswith("agents.")
            if words[2] == "agents.identify":  # record and fit, as written
                assert identify.main(words[3:]) == 0
            else:  # the other programs that take the result: their arguments as written
                importlib.import_module(words[2]).build_parser().parse_args(words[3:])
    for block in re.findall(r"```python\n(.*?)```", text, re.S):
        exec(compile(block, str(page), "exec"), {})
    out = capsys.readouterr().out
    nominal = float(re.search(r"^nominal ([\d.]+)$", out, re.M).group(1))
    found = float(re.search(r"^identified ([\d.]+)$", out, re.M).group(1))
    assert nominal < 0.5 and found >= 0.95
