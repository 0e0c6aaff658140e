"""Recording an exciting input on any Lagrange env, and fitting a record, for `dynamics.identify`.

The env is made with the plant's parameters (`gym.make(spec(env_id), **plant)`) and stepped
without its time limit; the excitation is a periodic multisine (`dynamics.excite`) in the
env's action units, a `fraction` of the action range. An env that ends early under the
open-loop input (a pole that falls past its failure angle) is recorded again with half the
excitation, then under its task's LQR (designed on the env's own model) with the
excitation added to its action: the regression uses the inputs applied, whatever produced
them. If every try ends early, the longest record is kept when it lasts `MIN_SECONDS`.
Each row holds the state at the start of a control period and the model inputs applied
over it (`info["input"]`), so the record is zero-order hold, as `identify` expects. Sensor
noise (Gaussian, std `noise = (positions, rates)`) is added to the recorded states only.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from dynamics.excite import multisine
from dynamics.regression import with_noise

from ..common import UserError, lagrange_env, spec, task_of

RATE = 100.0
"""Samples per second of a record (the env stepped at this control rate): at an env's own
20 Hz, positions-only records of the arm were biased by -24 % to -59 % and the momentum
form's quadrature error, of order (omega h)^4, is 625 times that at 100 Hz."""
MIN_SECONDS = 5.0
"""The shortest record kept when every try ends early."""
CLOSED_LOOP_PERIOD = 2.0
"""Period (s) of the excitation under feedback: its harmonics from 0.5 Hz up, above what
LQR cancels (at a 10 s period, the cart-pole's LQR cancelled the excitation to an input std
of 2 % of the range, and the record told its masses only to +-100 %)."""


def record(
    env_id: str,
    seconds: float = 20.0,
    plant: dict | None = None,
    noise: tuple[float, float] = (0.0, 0.0),
    fraction: float = 0.5,
    seed: int = 0,
    feedback: str | None = None,
    candidates: int = 1,
    rate: float | None = RATE,
) -> dict[str, np.ndarray]:
    """A record {t, q, qd, u, ...} of `seconds` of excitation on `env_id` with `plant`
    (`gym.make` keyword arguments: the model's parameters, options such as max_input).
    feedback: None (open loop, then LQR if the env ends early), "none" or "lqr".
    candidates: excitations (phases seeded seed, seed + 1, ...) tried first on the env's
    nominal model, the one whose record gives the best conditioned regressor (the
    identification's condition number) then run on the plant. Also returns the plant's
    parameters (`plant_names`, `plant_values`), the noise and the env id, for the report.
    rate: samples per second (the env made with control_period = 1 / rate; None: the env's
    own control period, 20 Hz for most)."""
    if not seconds > 0:
        raise UserError(f"seconds must be positive, got {seconds}.")
    if len(noise) != 2 or not all(np.isfinite(v) and v >= 0 for v in noise):
        raise UserError(f"noise must be two stds >= 0 (positions, rates), got {noise}.")
    if int(candidates) < 1:
        raise UserError(f"candidates must be at least 1, got {candidates}.")
    if rate is not None and not (np.isfinite(rate) and 1.0 <= rate <= 10_000.0):
        raise UserError(f"rate must be in [1, 10000] samples per second, got {rate}.")
    plant = dict(plant or {})
    if rate is not None:
        plant.setdefault("control_period", 1.0 / rate)
    if candidates > 1:
        seed = best_excitation(env_id, seconds, plant, fraction, seed, feedback, candidates)
    env = lagrange_env(gym.make(spec(env_id), **plant))
    rec, mode = _excite(env, env_id, seconds, fraction, seed, feedback)
    n = env.system.n_q
    rec = with_noise(rec, noise, seed + 1)
    params = env.system.parameters
    rec |= {
        "plant_names": np.array(list(params)),
        "plant_values": np.array(list(params.values())),
        "noise": np.array(noise, dtype=float),
        "env_id": np.array(env_id),
        "feedback": np.array(mode),
        "coordinates": np.array(env.system.coordinates[:n]),
    }
    return rec


def _excite(env, env_id: str, seconds: float, fraction: float, seed: int, feedback):
    """(record, mode): open loop, then half the excitation, then under LQR (or `feedback`
    alone), until one lasts `seconds`; else the longest if it lasts MIN_SECONDS."""
    tries = (
        [(feedback, fraction)]
        if feedback
        else [("none", fraction), ("none", fraction / 2), ("lqr", fraction)]
    )
    best, mode = None, None
    for how, share in tries:
        rec = _run(env, seconds, share, seed, how)
        if rec is not None and (best is None or len(rec["t"]) > len(best["t"])):
            best, mode = rec, how
        if rec is not None and rec["t"][-1] >= seconds - 1e-9:
            break
    if best is None or best["t"][-1] < MIN_SECONDS:
        raise UserError(
            f"{env_id} ended within {MIN_SECONDS} s under every excitation tried "
            f"({', '.join(m for m, _ in tries)}); try a smaller --fraction."
        )
    return best, mode


def model_of(env_id: str):
    """The `dynamics.Model` an env's task runs on."""
    from dynamics.regressor import as_model

    return as_model(task_of(env_id).model)


def fit(env_id: str, data: dict, unknown=None, friction=None, given=None, noise=None):
    """`dynamics.identify.identify` on an env's model. noise: the sensors' stds where known;
    None takes the record's own `noise` entry (a record made by `record` carries it), else
    leaves it to `identify` to estimate."""
    from dynamics.identify import identify

    record = {k: data[k] for k in ("t", "q", "qd", "u") if k in data}
    if noise is None and "noise" in data:
        noise = tuple(np.asarray(data["noise"], dtype=float).tolist())
    try:
        return identify(model_of(env_id), record, unknown, friction, given=given, noise=noise)
    except (TypeError, ValueError) as exc:
        raise UserError(str(exc)) from None


def best_excitation(env_id, seconds, plant, fraction, seed, feedback, candidates) -> int:
    """The seed of the excitation, of `candidates` tried on the nominal model (with the
    plant's options that are not model parameters, e.g. its motors), whose record the
    identification finds best conditioned."""
    names = lagrange_env(gym.make(spec(env_id))).system.parameters
    options = {k: v for k, v in plant.items() if k not in names}
    env = lagrange_env(gym.make(spec(env_id), **options))
    scores = {}
    for s in range(seed, seed + int(candidates)):
        rec, _ = _excite(env, env_id, seconds, fraction, s, feedback)
        scores[s] = fit(env_id, rec | {"noise": np.zeros(2)}).condition
    return min(scores, key=scores.get)


def _run(env, seconds: float, fraction: float, seed: int, mode: str):
    """The record under `mode` ("none" or "lqr") up to the step before the env ended, or
    None (no LQR for this task)."""
    h = float(env.control_period)
    steps = int(round(seconds / h))
    n_a = env.action_space.shape[0]
    period = min(10.0 if mode == "none" else CLOSED_LOOP_PERIOD, seconds / 2)
    excite = multisine(np.ones(n_a), period=period, fraction=fraction, seed=seed)
    policy = None
    if mode == "lqr":
        if env.task.lqr is None:
            return None
        from .lqr_policy import LQRPolicy

        policy = LQRPolicy(env)
    obs, _ = env.reset(seed=seed)
    X, U = [], []
    for k in range(steps + 1):
        action = excite(k * h)
        if policy is not None:
            action = action + policy.predict(obs)[0]
        x = env.state
        obs, _, terminated, _, info = env.step(np.clip(action, -1, 1).astype(np.float32))
        if terminated:
            break
        X.append(x)
        U.append(info["input"])
    if len(X) < 2:
        return {"t": np.zeros(1)}
    X = np.array(X)
    n = X.shape[1] // 2
    return {"t": np.arange(len(X)) * h, "q": X[:, :n], "qd": X[:, n:], "u": np.array(U)}
