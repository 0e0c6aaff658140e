"""Interrupted training loses nothing: signals save and exit, killed writes are cleaned up,
a resumed run evaluates where an uninterrupted one does and keeps its replay buffer."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3 import PPO, SAC

import envs
from agents import train as train_mod
from agents.common import UserError, atomic_path
from agents.learning import budget
from agents.learning.callbacks import load_replay_buffer, save_replay_buffer
from agents.learning.rundir import is_stale_temporary, latest_checkpoint
from agents.train import TrainingInterrupted, train

BEAD = next(env_id for env_id in envs.ENV_IDS if "/BeadOnRod-" in env_id)
# one env, so PPO's rollouts are the task's n_steps (256) and counts move one step at a time
SMALL = dict(algo="ppo", n_envs=1, eval_episodes=1, progress=False)
REPO = Path(__file__).resolve().parents[2]


def _eval_steps(run_dir: Path) -> list[int]:
    return [int(r.split(",")[0]) for r in (run_dir / "eval.csv").read_text().splitlines()[1:]]


class _SignalAt(train_mod.GracefulStop):
    """Delivers `send` to this process when the count reaches `at`, through the real
    handler (signal.raise_signal runs it before returning)."""

    at, send = 300, signal.SIGINT

    def _on_step(self) -> bool:
        if self.model.num_timesteps == self.at:
            signal.raise_signal(self.send)
        return super()._on_step()


# One handler (GracefulStop.SIGNALS) takes both signals: SIGINT trains in the fast suite,
# SIGTERM (its own disposition and exit code) with -m slow, each a training of ~1.5 s
@pytest.mark.parametrize(
    "signum",
    [signal.SIGINT, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)],
    ids=["SIGINT", "SIGTERM"],
)
def test_a_signal_saves_the_model_and_a_checkpoint_the_run_resumes_from(
    signum, tmp_path, monkeypatch
):
    monkeypatch.setattr(_SignalAt, "send", signum)
    monkeypatch.setattr(train_mod, "GracefulStop", _SignalAt)
    # the disposition an interactive run has; a shell without job control starts background
    # jobs (as a CI runner may start the tests) with SIGINT ignored, which train() respects
    default = signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL
    previous = signal.signal(signum, default)
    try:
        with pytest.raises(TrainingInterrupted) as stopped:
            train(BEAD, timesteps=2048, run_dir=tmp_path, eval_freq=256, **SMALL)
        assert signal.getsignal(signum) is default  # the handler is put back
    finally:
        signal.signal(signum, previous)
    assert stopped.value.exit_code == 128 + signum
    # stopped at 300, inside the second rollout: kept is what the weights learnt from
    result = stopped.value.result
    assert result.timesteps == 256 and result.model.num_timesteps == 256
    assert latest_checkpoint(tmp_path / "checkpoints")[0] == 256
    assert _eval_steps(tmp_path) == [256]
    episodes = (tmp_path / "episodes.csv").read_text().splitlines()[1:]
    assert all(int(row.split(",")[0]) <= 256 for row in episodes)
    model = PPO.load(tmp_path / "model.zip", device="cpu")
    assert model.num_timesteps == 256 and (tmp_path / "vecnormalize.pkl").exists()
    monkeypatch.undo()
    resumed = train(BEAD, timesteps=512, run_dir=tmp_path, eval_freq=256, resume=True, **SMALL)
    assert resumed.timesteps == 512 and _eval_steps(tmp_path) == [256, 512]


def _wait_for(path: Path, process: subprocess.Popen, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            out, err = process.communicate()
            pytest.fail(f"training never wrote {path.name}:\n{out}\n{err}")
        time.sleep(0.05)


@pytest.mark.slow
def test_ctrl_c_on_the_command_line_saves_a_loadable_model_and_exits_130(tmp_path):
    argv = [sys.executable, "-m", "agents.train", BEAD, "--timesteps", "100000"]
    argv += ["--n-envs", "1", "--eval-freq", "256", "--eval-episodes", "1"]
    argv += ["--run-dir", str(tmp_path), "--no-progress"]
    env = dict(os.environ, OMP_NUM_THREADS="1", SDL_VIDEODRIVER="dummy", MPLBACKEND="Agg")
    process = subprocess.Popen(
        argv,
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # a shell without job control starts background jobs with SIGINT ignored; undo that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    _wait_for(tmp_path / "eval.csv", process, timeout=120)  # it has started stepping
    sent = time.monotonic()
    process.send_signal(signal.SIGINT)
    try:
        _, err = process.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        pytest.fail("training went on after Ctrl-C")
    took = time.monotonic() - sent
    assert process.returncode == 130, err
    assert took < 10, f"took {took:.1f} s to stop"
    last = err.strip().splitlines()[-1]
    assert last.startswith("Interrupted at ") and "--resume" in last, err
    assert "Traceback" not in err
    model = PPO.load(tmp_path / "model.zip", device="cpu")
    action, _ = model.predict(model.observation_space.sample(), deterministic=True)
    assert model.action_space.contains(action)
    steps, _ = latest_checkpoint(tmp_path / "checkpoints")
    assert steps == model.num_timesteps > 0


def test_the_temporary_names_of_atomic_writes_are_recognised(tmp_path):
    for name in ("model.zip", "eval.csv", "rl_model_replay_buffer_1200_steps.pkl"):
        with atomic_path(tmp_path / name) as tmp:
            assert is_stale_temporary(tmp.name), tmp.name
    for name in (".notes.txt.abcdefgh.txt", "model.zip", ".model.zip", ".rl_model_1.zip.abcdefgh"):
        assert not is_stale_temporary(name), name


@pytest.mark.slow
def test_resume_removes_what_killed_writes_left_behind(tmp_path):
    train(BEAD, timesteps=256, run_dir=tmp_path, eval_freq=256, **SMALL)
    ckpt = tmp_path / "checkpoints"
    stale = [
        ckpt / ".rl_model_replay_buffer_512_steps.pkl.k2j4_x9a.pkl",
        ckpt / ".rl_model_512_steps.zip.0abcdefg.zip",
        tmp_path / ".model.zip.zz_12345.zip",
        tmp_path / ".learning_curve.png.abcdefgh.png",
        tmp_path / ".staging" / "evaluations.npz",
    ]
    foreign = [tmp_path / ".notes.txt.abcdefgh.txt", ckpt / "mine.zip"]
    for path in stale + foreign:
        path.parent.mkdir(exist_ok=True)
        path.write_bytes(b"half written")
    result = train(BEAD, timesteps=512, run_dir=tmp_path, eval_freq=256, resume=True, **SMALL)
    assert result.timesteps == 512
    assert not [p for p in stale if p.exists()]
    assert all(p.exists() for p in foreign)
    again = train(BEAD, timesteps=512, run_dir=tmp_path, eval_freq=256, resume=True, **SMALL)
    assert again.timesteps == 512  # a finished run resumes to nothing to do


@pytest.mark.slow  # trains three times: ~2.2 s
def test_a_resumed_run_evaluates_on_the_same_timesteps_as_an_uninterrupted_one(tmp_path):
    # evaluations every 384 steps; the first part stops at its 512-step checkpoint
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    train(BEAD, timesteps=1024, run_dir=whole, eval_freq=384, **SMALL)
    train(BEAD, timesteps=512, run_dir=parts, eval_freq=384, **SMALL)
    train(BEAD, timesteps=1024, run_dir=parts, eval_freq=384, resume=True, **SMALL)
    assert _eval_steps(whole) == [384, 768]
    assert _eval_steps(parts) == _eval_steps(whole)  # not 384, 896 (512 + 384)
    with np.load(parts / "evaluations.npz") as data:  # SB3's record continues too
        assert list(data["timesteps"]) == [384, 768]


def _filled_sac(n: int) -> SAC:
    model = SAC("MlpPolicy", "Pendulum-v1", buffer_size=100_000, device="cpu", seed=0)
    rng = np.random.default_rng(0)
    for _ in range(n):
        obs = rng.normal(size=(1, 3)).astype(np.float32)
        act = rng.uniform(-2, 2, size=(1, 1)).astype(np.float32)
        model.replay_buffer.add(obs, obs + 1, act, rng.normal(size=1), np.array([False]), [{}])
    return model


def test_a_replay_buffer_checkpoint_holds_the_filled_rows_only(tmp_path):
    model = _filled_sac(1200)
    save_replay_buffer(model, tmp_path / "trimmed.pkl")
    model.save_replay_buffer(tmp_path / "full.pkl")
    trimmed, full = ((tmp_path / name).stat().st_size for name in ("trimmed.pkl", "full.pkl"))
    assert trimmed < full / 50, (trimmed, full)
    restored = _filled_sac(0)
    load_replay_buffer(restored, tmp_path / "trimmed.pkl")
    before, after = model.replay_buffer, restored.replay_buffer
    assert after.size() == 1200 and after.buffer_size == before.buffer_size
    for name in ("observations", "next_observations", "actions", "rewards", "dones"):
        np.testing.assert_array_equal(getattr(after, name), getattr(before, name), name)
    obs = np.zeros((1, 3), np.float32)  # the restored capacity takes new rows
    after.add(obs, obs, np.zeros((1, 1), np.float32), np.zeros(1), np.array([True]), [{}])
    assert after.size() == 1201


@pytest.mark.slow
def test_resume_refuses_a_checkpoint_without_its_replay_buffer(tmp_path):
    kwargs = dict(algo="sac", eval_freq=1000, eval_episodes=1, progress=False, run_dir=tmp_path)
    train(BEAD, timesteps=200, **kwargs)
    (tmp_path / "checkpoints" / "rl_model_replay_buffer_200_steps.pkl").unlink()
    with pytest.raises(UserError, match="--allow-missing-buffer"):
        train(BEAD, timesteps=300, resume=True, **kwargs)
    result = train(BEAD, timesteps=300, resume=True, allow_missing_buffer=True, **kwargs)
    assert result.timesteps == 300 and result.model.replay_buffer.size() == 100


@pytest.mark.slow
def test_a_signal_during_an_evaluation_ends_it_at_the_next_step_and_saves(tmp_path, monkeypatch):
    """SB3 looks at callbacks only between evaluations; the evaluation polls the stop."""
    calls = []

    class SignalInEval(budget.BudgetedEval):  # the evaluation train() makes
        def _log_success_callback(self, locals_, globals_):
            calls.append(self.num_timesteps)
            if len(calls) == 3:
                signal.raise_signal(signal.SIGTERM)
            super()._log_success_callback(locals_, globals_)

    monkeypatch.setattr(budget, "BudgetedEval", SignalInEval)
    previous = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        with pytest.raises(TrainingInterrupted) as stopped:
            # 50 evaluation episodes of 500 steps would take a minute
            options = {**SMALL, "eval_episodes": 50}
            train(BEAD, timesteps=2048, run_dir=tmp_path, eval_freq=300, **options)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert len(calls) == 3  # the step that saw the signal ended it, not 50 episodes later
    assert stopped.value.result.timesteps == 256  # the first rollout, which the weights hold
    assert latest_checkpoint(tmp_path / "checkpoints")[0] == 256
    assert PPO.load(tmp_path / "model.zip", device="cpu").num_timesteps == 256
