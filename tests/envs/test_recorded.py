"""Every env steps bit for bit as the trajectories recorded in `data/recorded.npz`: single
envs, vector envs (shared, per-copy and randomised parameters, observed parameters,
mid-episode redraws, once-only draws, constants that follow each copy), perturbed envs
(noise, motor, delay, pushes), the step of separate calls and an env's simulator.

The file was written by this module (`python -m tests.envs.test_recorded`), run on the
code before the plant and its parameter store were rebuilt; a change that moves any of
these numbers by one bit fails here. Write it again only for a change that is meant to
move them (and bump the versions of the envs whose dynamics, rewards or termination it
changes)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import envs
from envs.randomize import LogUniform, TruncNormal, Uniform
from tests.binding import bound
from tests.matrix import FAST, over

DATA = Path(__file__).parent / "data" / "recorded.npz"
ARM, CRANK, DISK = "Lagrange/TwoLinkArm-v1", "Lagrange/CrankSlider-v1", "Lagrange/RollingDisk-v1"
PERTURB = {"obs_noise": 0.01, "action_noise": 0.2, "motor_k": 0.6, "delay": 1,
           "push": {"force": 15.0, "every": 0.3}}  # fmt: skip
RANDOM = {"m2": (0.8, 1.6), "Ibar1": Uniform(0.8, 1.2, apply="scale"),
          "l1": TruncNormal(1.0, 0.05, 0.9, 1.1, apply="scale", when="construction"),
          "Ibar2": LogUniform(0.05, 0.12, when=7)}  # fmt: skip


def _single(env_id, steps=50, **kwargs):
    env = gym.make(env_id, **kwargs)
    rng = np.random.default_rng(1)
    out = []
    obs, info = env.reset(seed=3)
    out += [obs.astype(np.float64), [info["energy"]]]
    for _ in range(steps):
        a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        out += [obs, [r, term, trunc, info["energy"]], info["state"], info["input"]]
        out += [np.array(list(info.get("params", {}).values()), dtype=np.float64)]
        out += [info.get("push", np.zeros(0))]
        if term or trunc:
            obs, info = env.reset()
            out += [obs, info["state"]]
    return np.concatenate([np.ravel(np.asarray(o, dtype=np.float64)) for o in out])


def _vector(env_id, n=5, steps=60, separate=False, **kwargs):
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)
    if separate:
        vec.unwrapped._rt.stepper.separate()  # the step of separate calls
    else:
        bound(vec)
    rng = np.random.default_rng(2)
    obs, info = vec.reset(seed=11)
    out = [obs, info["state"], info["energy"]]
    for _ in range(steps):
        a = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = vec.step(a)
        out += [obs, r, term, trunc, info["state"], info["input"], info["energy"]]
        out += [np.array([info["params"][k] for k in sorted(info.get("params", {}))
                          if not k.startswith("_")])]  # fmt: skip
        out += [info.get("push", np.zeros(0))]
        if "constraint_residual" in info:
            out += [info["constraint_residual"]]
    return np.concatenate([np.ravel(np.asarray(o, dtype=np.float64)) for o in out])


def _simulator(env_id, n=4, steps=30):
    env = gym.make(env_id, m2=1.3).unwrapped
    env.reset(seed=0)
    sim = env.simulator(n)
    rng = np.random.default_rng(4)
    x = np.tile(env.state, (n, 1)) + rng.normal(0, 0.1, (n, env.system.state_size))
    sim.reset_rows(slice(None), x, np.tile(env.goal, (n, 1)))
    out = []
    for _ in range(steps):
        sim.step(rng.uniform(-1, 1, (n, len(env.plant.actuated))), 200)
        out += [sim.X.copy(), sim.O.copy(), sim.R.copy(), sim.terminated.copy()]
    return np.concatenate([np.ravel(np.asarray(o, dtype=np.float64)) for o in out])


CASES = {
    **{f"single {i}": (lambda i=i: _single(i)) for i in envs.ENV_IDS},
    "single arm m2=2": lambda: _single(ARM, m2=2.0),
    "single arm randomised": lambda: _single(ARM, randomize=RANDOM, observe_params=True),
    "single arm perturbed": lambda: _single(ARM, perturb=PERTURB),
    "single arm perturbed randomised": lambda: _single(
        ARM, perturb=PERTURB, randomize={"m2": (0.8, 1.6)}
    ),
    "vector arm": lambda: _vector(ARM),
    "vector arm m2=2 separate": lambda: _vector(ARM, separate=True, m2=2.0),
    "vector arm randomised": lambda: _vector(ARM, randomize=RANDOM, observe_params=("m2", "l1")),
    "vector arm randomised separate": lambda: _vector(ARM, separate=True, randomize=RANDOM),
    "vector arm exact values": lambda: _vector(ARM, randomize={}),
    "vector arm perturbed": lambda: _vector(ARM, perturb=PERTURB),
    "vector arm perturbed randomised": lambda: _vector(
        ARM, perturb=PERTURB, randomize=RANDOM, observe_params=True
    ),
    "vector crank randomised": lambda: _vector(CRANK, randomize={"m": (0.5, 2.0)}),
    "vector disk randomised": lambda: _vector(DISK, n=3, randomize={"r": (0.25, 0.35)}),
    "vector disk perturbed": lambda: _vector(DISK, n=3, perturb={"action_noise": 0.05}),
    "simulator arm": lambda: _simulator(ARM),
    "vector arm perturbed randomised separate": lambda: _vector(
        ARM, separate=True, perturb=PERTURB, randomize=RANDOM, observe_params=True
    ),
    "vector arm perturbed separate": lambda: _vector(ARM, separate=True, perturb=PERTURB),
    "vector crank randomised separate": lambda: _vector(
        CRANK, separate=True, randomize={"m": (0.5, 2.0)}
    ),
    "vector disk randomised separate": lambda: _vector(
        DISK, n=3, separate=True, randomize={"r": (0.25, 0.35)}
    ),
}


def record() -> None:
    """Write the recorded trajectories (see the module docstring)."""
    import warnings

    DATA.parent.mkdir(exist_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arrays = {name: fn() for name, fn in CASES.items()}
    tmp = DATA.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    tmp.replace(DATA)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize(
    "case",
    [c for c in CASES if not c.startswith("single Lagrange/")]
    + over(
        (c for c in CASES if c.startswith("single Lagrange/")),
        fast=[f"single {i}" for i in FAST],
    ),
)
def test_steps_bit_for_bit_as_recorded(case):
    expected = np.load(DATA)[case]
    got = CASES[case]()
    assert got.shape == expected.shape
    assert np.array_equal(got, expected, equal_nan=True)


if __name__ == "__main__":
    record()
