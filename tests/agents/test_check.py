"""The main job on one environment with a tiny budget: table, findings, files; budgets and
hyperparameters against the runs on disk; training time kept across a resumed run."""

from __future__ import annotations

import json
import signal

import pytest
import yaml

import envs
from agents import check as check_mod
from agents import train as train_mod
from agents.check import TIME_FILE, build_parser, main, record_segment, run_check
from agents.common import UserError
from agents.learning import budget as budgets
from agents.learning import confirm as confirmation
from agents.learning.rundir import finished_run

ARM = next(env_id for env_id in envs.ENV_IDS if "/TwoLinkArm-" in env_id)
ARM_DIR = "train/" + ARM.replace("/", "-")
REPORT = ARM.replace("/", "-")  # the report of run_check([ARM]): out/REPORT, its links relative


@pytest.fixture
def tiny(tmp_path):
    """Hyperparameters for rollouts of 64 steps on one env (fast, and several per run)."""
    path = tmp_path / "tiny.yml"
    path.write_text(yaml.safe_dump({ARM: {"n_envs": 1, "n_steps": 64, "batch_size": 64}}))
    return path


def report_of(timesteps):
    """run_check([ARM], timesteps=N)'s report directory's name (one per budget)."""
    return f"{REPORT}_{timesteps}steps"


def check(out, timesteps, hyperparams=None, fresh=False):
    return run_check(
        [ARM], episodes=2, out=out, timesteps=timesteps, progress=False,
        hyperparams=hyperparams, fresh=fresh,
    )  # fmt: skip


@pytest.mark.slow
def test_check_writes_the_comparison(tmp_path, capsys, tiny):
    out = tmp_path / "check"
    (out / "results.md").parent.mkdir()
    (out / "results.md").write_text("the report of every env, from an earlier invocation")
    rows = check(out, 128, tiny)
    # the envs given get a report of their own; the earlier report stays
    assert (out / "results.md").read_text().startswith("the report of every env")
    report_dir, out = out, out / report_of(128)
    agents = [r.agent for r in rows]
    assert agents[:4] == ["random", "zero", "heuristic", "lqr"] and agents[-1] == "ppo"
    # the agent the task does not declare is in the report with its reason, not left out
    assert f"| {ARM} | plan | not run |" in (out / "results.md").read_text()
    printed = capsys.readouterr().out
    assert f"| {ARM} | lqr |" in printed and "lqr" in printed
    for name in ("results.md", "results.csv", "comparison.png"):
        assert (out / name).stat().st_size > 0
    report = (out / "results.md").read_text()
    assert "## Findings" in report and "| environment | agent | success [95 % CI] |" in report
    # the header names the algorithm and the budget, and links the learning curve
    run_dir = f"{ARM_DIR}/ppo_seed0_128steps"
    assert f"- {ARM}: PPO, 128 steps (128 trained in " in report
    assert f"[learning curve](../{run_dir}/learning_curve.png)" in report
    assert (report_dir / run_dir / "learning_curve.png").exists()
    assert f"Report, CSV and plot in {out}/" in printed
    assert all(sum(r.stats.endings().values()) == 2 for r in rows)
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 1 + len(rows) + 1  # the rows, then the plan's "not run" line
    assert csv_lines[-1].startswith(f"{ARM},plan,") and "the task declares no" in csv_lines[-1]
    # a second run reuses the finished training, and its stored training time
    again = check(report_dir, 128, tiny)
    assert again[-1].stats.returns.tolist() == rows[-1].stats.returns.tolist()
    assert again[-1].training.train_s == rows[-1].training.train_s > 0
    assert (
        again[-1].training.now_s == 0.0
        and "0 s of it in this run" in (out / "results.md").read_text()
    )


@pytest.mark.slow  # trains twice
def test_another_budget_trains_a_fresh_run_and_keeps_the_earlier(tmp_path, tiny):
    first = check(tmp_path, 64, tiny)[-1].training
    second = check(tmp_path, 192, tiny)[-1].training
    assert (first.budget, first.timesteps) == (64, 64)
    assert (second.budget, second.timesteps) == (192, 192)  # trained from 0, not from 64
    assert first.run_dir != second.run_dir
    for t in (first, second):
        assert (tmp_path / report_of(t.budget) / t.run_dir / "model.zip").exists()
    # each budget's report is kept beside the other's
    for budget in (64, 192):
        report = (tmp_path / report_of(budget) / "results.md").read_text()
        assert f"PPO, {budget} steps" in report
    time_file = tmp_path / report_of(192) / second.run_dir / TIME_FILE
    segments = json.loads(time_file.read_text())["segments"]
    assert [(s["from"], s["to"]) for s in segments] == [(0, 192)]


@pytest.mark.slow  # trains twice
def test_a_run_with_other_hyperparameters_is_refused_until_fresh(tmp_path, tiny, capsys):
    run = check(tmp_path, 64, tiny)[-1].training
    changed = tmp_path / "changed.yml"
    changed.write_text(yaml.safe_dump({ARM: {"n_envs": 1, "n_steps": 64, "batch_size": 32}}))
    with pytest.raises(UserError, match=r"batch_size: 64 in the run, 32 now.*--fresh"):
        check(tmp_path, 64, changed)
    argv = [ARM, "--timesteps", "64", "--hyperparams", str(changed), "--out", str(tmp_path)]
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(argv + ["--episodes", "2", "--no-progress"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1 and "--fresh" in err
    retrained = check(tmp_path, 64, changed, fresh=True)[-1].training
    config = yaml.safe_load((tmp_path / report_of(64) / run.run_dir / "config.yml").read_text())
    assert retrained.run_dir == run.run_dir and config["hyperparams"]["batch_size"] == 32


class _StopAt(train_mod.GracefulStop):
    """SIGINT once the run passes 100 steps (in its second 64-step rollout)."""

    def _on_step(self) -> bool:
        if self.model.num_timesteps > 100 and self.signum is None:
            signal.raise_signal(signal.SIGINT)
        return super()._on_step()


@pytest.mark.slow
def test_training_time_is_kept_across_an_interrupted_run(
    tmp_path, tiny, monkeypatch, interactive_sigint
):
    with monkeypatch.context() as patch:
        patch.setattr(train_mod, "GracefulStop", _StopAt)
        with pytest.raises(train_mod.TrainingInterrupted):
            check(tmp_path, 256, tiny)
    run_dir = tmp_path / ARM_DIR / "ppo_seed0_256steps"
    (before,) = json.loads((run_dir / TIME_FILE).read_text())["segments"]
    assert before["from"] == 0 and 0 < before["to"] < 256
    training = check(tmp_path, 256, tiny)[-1].training
    segments = json.loads((run_dir / TIME_FILE).read_text())["segments"]
    assert [(s["from"], s["to"]) for s in segments] == [(0, before["to"]), (before["to"], 256)]
    assert training.train_s == pytest.approx(sum(s["seconds"] for s in segments))
    assert training.timed_steps == training.timesteps == 256


def test_segments_past_the_resumed_checkpoint_are_dropped(tmp_path):
    assert record_segment(tmp_path, 0, 1000, 2.0) == (2.0, 1000)
    assert record_segment(tmp_path, 1000, 2000, 3.0) == (5.0, 2000)
    assert record_segment(tmp_path, 1000, 1500, 1.0) == (3.0, 1500)  # resumed at 1000 again
    assert record_segment(tmp_path, 0, 500, 0.5) == (0.5, 500)  # a fresh run


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


def test_an_agent_that_refuses_is_reported_with_its_reason(tmp_path, tiny, monkeypatch):
    from agents import check as check_mod
    from envs.checks import Unsupported

    scored = check_mod.learned.warm_evaluate

    def lqr_refuses(evaluate, env_id, agent, episodes, seed):
        if agent == "lqr":
            raise Unsupported("lqr designs on the dynamics at one time,\n and this is not so")
        return scored(evaluate, env_id, agent, episodes, seed)

    monkeypatch.setattr(check_mod.learned, "warm_evaluate", lqr_refuses)
    rows = check(tmp_path, 128, tiny)
    assert "lqr" not in [r.agent for r in rows]
    report = (tmp_path / report_of(128) / "results.md").read_text()
    reason = "refused: lqr designs on the dynamics at one time, and this is not so"
    assert f"| {ARM} | lqr | not run |" in report and f"{reason} |" in report
    table = [line for line in report.splitlines() if line.startswith("| ")]
    assert len({line.count("|") for line in table}) == 1  # every row has every column
    csv_text = (tmp_path / report_of(128) / "results.csv").read_text()
    assert f"{ARM},lqr," in csv_text and f"not run: {reason}" in csv_text


def test_each_budget_reports_in_a_directory_of_its_own(tmp_path):
    from agents.check import report_dir

    assert report_dir(tmp_path, []) == tmp_path  # the main job's report: runs/check/
    assert report_dir(tmp_path, [ARM]) == tmp_path / REPORT
    assert report_dir(tmp_path, [ARM], 5000) == tmp_path / f"{REPORT}_5000steps"
    assert report_dir(tmp_path, [ARM], None, 90.0) == tmp_path / f"{REPORT}_90s"
    assert report_dir(tmp_path, [], 5000) == tmp_path / "all_5000steps"
    randomized = report_dir(tmp_path, [ARM], 64, None, {"inertial": 0.25})
    assert randomized.name == f"{REPORT}_64steps_randomized-inertial0.25"
    assert "another budget keeps the earlier report" in " ".join(
        build_parser().format_help().split()
    )


# ---- a budget of time: a solved run is reused, any other trains afresh ---------------------
BEAD = next(env_id for env_id in envs.ENV_IDS if "/BeadOnRod-" in env_id)


def _finished_run(run_dir, **config):
    """A run directory as a solved budget run leaves it (its files' contents aside)."""
    run_dir.mkdir(parents=True)
    (run_dir / "config.yml").write_text(yaml.safe_dump(config))
    (run_dir / "model.zip").write_bytes(b"")
    (run_dir / "solved.json").write_text("{}")
    return run_dir


def test_a_run_is_reused_where_it_finished_with_the_settings_it_trained(tmp_path):
    config = dict(env_id=BEAD, algo="ppo", seed=0, budget_s=600.0, hyperparams={"gamma": 0.98})
    config["n_timesteps"] = 200_000  # the declared steps, a cap
    run_dir = _finished_run(tmp_path / "run", **config, task="abc")
    now = {**config, "task": "abc"}
    assert finished_run(run_dir, now, trained=120_000)  # solved
    for other in ({"seed": 1}, {"budget_s": 300.0}, {"hyperparams": {"gamma": 0.99}}):
        assert not finished_run(run_dir, {**now, **other}, trained=120_000), other
    assert not finished_run(run_dir, {**now, "task": "another declaration"}, trained=120_000)
    (run_dir / "solved.json").unlink()  # not solved: reused where it trained its cap,
    assert finished_run(run_dir, now, trained=200_704)  # where the clock did not decide
    assert not finished_run(run_dir, now, trained=150_000)  # it ran out of time: afresh


@pytest.mark.slow  # a run to its (forced) solution, about 3 s each
@pytest.mark.parametrize("cap", [None, 10_000])  # a time budget, without and with a step cap
def test_the_check_reuses_a_solved_run_and_fresh_retrains_it(tmp_path, monkeypatch, cap):
    monkeypatch.setattr(budgets, "SOLVED_RATE", 0.0)  # any evaluation counts as solved
    monkeypatch.setattr(confirmation, "RATE", 0.0)  # and any confirmation confirms it
    monkeypatch.setattr(confirmation, "EPISODES", 4)
    run_dir = tmp_path / "run"
    kw = dict(eval_episodes=2, progress=False, eval_freq=512)  # the YAML's copies, as check
    trained = train_mod.train(BEAD, run_dir=run_dir, timesteps=cap, budget=600, **kw)
    assert trained.timesteps == 1536  # solved at the third evaluation
    record_segment(run_dir, 0, trained.timesteps, trained.wall_s)  # as train_timed does
    called = []
    monkeypatch.setattr(check_mod, "train", lambda *a, **k: called.append(k) or trained)
    args = (BEAD, "ppo", 200_000, 0, run_dir, False, False, None, None)
    model, training = check_mod.train_timed(*args, seconds=600, cap=cap)
    assert called == [] and model == run_dir / "model.zip"
    assert (training.timesteps, training.now_s) == (trained.timesteps, 0.0)
    check_mod.train_timed(*args[:5], True, *args[6:], seconds=600, cap=cap)  # --fresh
    assert called[-1]["overwrite"] and not called[-1]["resume"]
    check_mod.train_timed(*args, seconds=300, cap=cap)  # not what it was solved in: afresh
    check_mod.train_timed(*args, seconds=600, cap=20_000 if cap else 5_000)
    assert len(called) == 3 and all(k["overwrite"] for k in called)
