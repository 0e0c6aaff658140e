"""benchmarks/robustness.py: its grids, where it says LQR drops below 50 %, the episodes it
counts, and a small run end to end (results, table and figure written)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
ARM, ACROBOT = "Lagrange/TwoLinkArm-v1", "Lagrange/Acrobot-v2"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("robustness", ROOT / "benchmarks/robustness.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["robustness"] = module
    spec.loader.exec_module(module)
    return module


def test_the_grids_span_the_robustness_criteria_s_ranges(bench):
    qs = {q.name: q for q in bench.quantities(ARM, 5, None)}
    assert {"m1", "m2", "Ibar1", "Ibar2", "inertial", "motor_k", "delay", "push"} <= set(qs)
    assert "l1" not in qs and "g" not in qs  # lengths and gravity are not inertial
    m2 = qs["m2"]
    assert [x for x, _ in m2.points] == [0.75, 0.875, 1.0, 1.125, 1.25]
    assert m2.points[0][1] == {"m2": 0.75}  # absolute values from the nominal 1 kg
    together = qs["inertial"].points[-1][1]
    assert together["m1"] == 1.25 and together["Ibar2"] == pytest.approx(1.25 / 12)
    assert [x for x, _ in qs["delay"].points] == [0, 1, 2]
    assert min(x for x, _ in qs["motor_k"].points) == 0.1
    assert max(x for x, _ in qs["motor_k"].points) == 2.0
    chosen = bench.quantities(ARM, 3, ["m2", "perturb"])
    assert [q.name for q in chosen] == ["m2", *bench.PERTURBATIONS]


def test_where_lqr_drops_below_half_is_the_grid_point_nearest_the_nominal(bench):
    from benchmarks.robustness_report import describe_drop, drop_points

    q = bench.Quantity("m2", "params", "", 1.0, tuple((x, {}) for x in (0.5, 0.75, 1, 1.25, 1.5)))
    rates = {0.5: 0.1, 0.75: 0.4, 1: 1.0, 1.25: 0.9, 1.5: 0.6}
    rows = [dict(agent="lqr", quantity="m2", x=x, rate=r) for x, r in rates.items()]
    drops = drop_points(rows, q)
    assert drops == {"nominal": 1.0, "below": (None, 0.75), "above": (1.5, None)}
    assert describe_drop(q, drops) == "falls below at 0.75; holds to 1.5"
    rows[0]["rate"], rows[1]["rate"] = 0.2, 0.6  # falls at 0.5, below 0.75 where it holds
    drops = drop_points(rows, q)
    assert describe_drop(q, drops) == "falls below at 0.5 (holds at 0.75); holds to 1.5"
    rows[2]["rate"] = 0.0  # already below at the nominal value
    assert describe_drop(q, drop_points(rows, q)) == ("below 50% at the nominal value already (0%)")


def test_each_copy_s_first_episode_is_counted_once(bench):
    from agents.evaluate import make_agent

    venv = bench._vec(ARM, 4, randomize={})
    won = bench.successes(venv, make_agent("zero", venv), [0, 1, 2, 3], None)
    assert won.shape == (4,) and won.dtype == bool and not won.any()


@pytest.mark.slow  # plans a swing-up (seconds)
def test_the_plan_tracker_follows_its_clock_on_a_plant_that_is_not_its_model(bench):
    """The tracker told the start only by episode_start keeps its plan running (a new plan at
    every step would restart the plan's clock at 0)."""
    venv = bench._vec(ACROBOT, 2, randomize={})
    policy = bench._plan_maker()(venv)
    obs, _ = venv.reset(seed=0, options={"params": {"m2": 1.2}})
    start = np.ones(2, dtype=bool)
    for _ in range(5):
        a, _ = policy.predict(obs, episode_start=start)
        obs = venv.step(a)[0]
        start[:] = False
    assert policy._k.tolist() == [5, 5]


@pytest.mark.slow
def test_a_small_run_writes_results_and_a_figure(bench, tmp_path, capsys):
    argv = ["--envs", ARM, "--agents", "lqr,ppo", "--quantities", "m2,delay", "--episodes",
            "3", "--grid", "3", "--no-train", "--models", str(tmp_path / "none"),
            "--out", str(tmp_path)]  # fmt: skip
    assert bench.main(argv) == 0
    results = json.loads((tmp_path / "results.json").read_text())
    env = results["envs"][ARM]
    assert env["agents"] == ["lqr"]  # no PPO model there, and --no-train
    rows = [r for r in env["rows"] if r["quantity"] == "m2"]
    assert [(r["x"], r["n"]) for r in rows] == [(0.75, 3), (1.0, 3), (1.25, 3)]
    assert all(r["low"] <= r["rate"] <= r["high"] for r in rows)
    delays = [(r["x"], r["n"]) for r in env["rows"] if r["quantity"] == "delay"]
    assert delays == [(0.0, 3), (1.0, 3), (2.0, 3)]
    # the arm's LQR holds at +-25 % of m2 and fails at a delay of one control period
    assert set(env["drops"]["lqr"]) == {"m2", "delay"}
    text = (tmp_path / "results.md").read_text()
    assert "controllers keep the nominal model" in text and "| m2 | 0.75 |" in text
    assert (tmp_path / "Lagrange-TwoLinkArm-v1.png").stat().st_size > 0
    assert (tmp_path / "model-based.png").stat().st_size > 0
    # two runs merged: the second run's agent joins the first's rows
    first = tmp_path / "first.json"
    (tmp_path / "results.json").rename(first)
    argv[argv.index("lqr,ppo")] = "heuristic"
    argv[argv.index("m2,delay")] = "m2"
    assert bench.main(argv) == 0
    merged = tmp_path / "merged"
    assert (
        bench.main(["--render", str(first), str(tmp_path / "results.json"), "--out", str(merged)])
        == 0
    )
    env = json.loads((merged / "results.json").read_text())["envs"][ARM]
    assert env["agents"] == ["lqr", "heuristic"] and len(env["rows"]) == 9  # 3 + 3 + 3
    assert len(json.loads((merged / "results.json").read_text())["runs"]) == 2


def test_each_perturbation_point_makes_its_env_with_the_agreed_option(bench, tmp_path, monkeypatch):
    """The grids of perturbations, run against a stand-in for the env option perturb= (the
    nominal point is made without it): one env per point, with the agreed keys."""
    made = []
    plain = bench._vec

    def vec(env_id, n, **options):
        made.append(options.pop("perturb", None))
        return plain(env_id, n, **options)

    monkeypatch.setattr(bench, "_vec", vec)
    monkeypatch.setattr(bench, "perturb_available", lambda env_id: None)
    argv = ["--envs", ARM, "--agents", "lqr", "--quantities", "delay,push", "--episodes", "2",
            "--grid", "2", "--no-train", "--out", str(tmp_path)]  # fmt: skip
    assert bench.main(argv) == 0
    assert made[:3] == [None, {"delay": 1}, {"delay": 2}]
    assert made[3] is None and made[4] == {"push": {"force": pytest.approx(0.5 * 2 * 9.81)}}
    rows = json.loads((tmp_path / "results.json").read_text())["envs"][ARM]["rows"]
    assert [r["x"] for r in rows] == [0.0, 1.0, 2.0, 0.0, 0.5]


@pytest.mark.slow  # designs the acrobot's LQR and its capture set
def test_a_policy_trained_with_a_hand_over_acts_with_it(bench):
    """As agents.evaluate acts: the acrobot's PPO hands over to LQR (on the nominal model),
    and a run trained with the holding input fed forward acts with it."""
    from agents.common import task_of
    from agents.control.handover import HandOverPolicy
    from agents.learning.feedforward import FeedForwardPolicy

    class Trained:  # an SB3Policy's two settings from its run
        handover = task_of(ACROBOT).hyperparams["ppo"]["handover"]
        feedforward = False

    plain = Trained()
    plain.handover = None
    venv = bench._vec(ACROBOT, 2, randomize={})
    assert isinstance(bench._trained_maker(Trained())(venv), HandOverPolicy)
    assert bench._trained_maker(plain)(venv) is plain
    fed = Trained()
    fed.handover, fed.feedforward = None, True
    acting = bench._trained_maker(fed)(venv)
    assert isinstance(acting, FeedForwardPolicy) and acting.policy is fed
