"""Perturbations of the plant an agent acts on: the env option `perturb=`, off by default.

    gymnasium.make("Lagrange/TwoLinkArm-v1", perturb={
        "obs_noise": 0.01,        # Gaussian std added to each observation feature
        "action_noise": 0.5,      # Gaussian std of each applied input, N*m or N
        "motor_k": 0.5,           # first-order motor response per control period
        "delay": 1,               # control periods of action delay
        "push": {"force": 20.0},  # random pushes at a point of the model, N
    })

Keys (each optional; `perturb=None` or `{}` is off: the env is what it was, bit for bit):

- `obs_noise`: std >= 0 of Gaussian noise added to each observation feature the agent
  gets, in the feature's units: one number for all features or one per feature. The noisy
  observation is clipped into `observation_space`; the state, reward, success and failure
  are computed from the true state.
- `action_noise`: std >= 0 of Gaussian noise added to the applied input, physical units
  (N*m or N): one number or one per actuated input.
- `motor_k`: the motor's response per control period, `u = u_prev + k (u_cmd - u_prev)`,
  k in (0, 2] (1: none; below 1 a lag, above 1 an overshoot): one number or one per input.
- `delay`: an int >= 0, control periods between a command and its effect; the input is 0
  until the first command arrives.
- `push`: a dict, random external pushes: `force` (N, required, >= 0: the magnitude of
  each push, its direction uniformly random in the point's plane or space), `every` (s,
  default 2.0: pushes start as a Poisson process of this mean interval, at control-period
  boundaries, while none acts), `duration` (s, default 0.1, rounded to whole control
  periods, at least one) and `point` (a point the model declares, default its first; see
  `dynamics.System.points`).

Per control period the agent's command (the clipped action as an input) passes through
the delay, then the motor response, then the noise, and is clipped to the input limits:
that is the input the model steps with (`info["input"]`). The reward's action terms see
the agent's clipped action, as without perturbations.

A push is a force f on a point of the model. It enters the equations of motion as the
generalised forces Q_s = f . dv/dqdot_s (virtual work, `dynamics.spec.generalized_forces`,
the machinery the models' own forces use), reaching every coordinate, actuated or not.
The model compiles that map (`dynamics.System.point_forces`); the force is evaluated at the
start of each control period and held over it like an input (zero-order hold), and the
integrator adds Q to the forcing vector (`Q = 0` steps bit for bit like no push). The
force acting is `info["push"]` (zeros when none).

Seeding: each copy's perturbations draw from a generator spawned from that copy's reset
generator at every reset (`Generator.spawn`, which draws nothing from it), so start states
are those of the unperturbed env, the single env and a vector env's copy with the same
seed are perturbed alike, and a reset clears the copy's delay line, motor state and push.
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

KEYS = ("obs_noise", "action_noise", "motor_k", "delay", "push")
PUSH_KEYS = ("force", "every", "duration", "point")
BUFFER = 64
"""Records of random numbers drawn at a time by each copy's generator (one per reset or
step): a Python call per copy and step would cost more than the step at N = 1024."""


def _unknown(keys, known, where: str) -> None:
    for key in keys:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"Unknown key {key!r} in {where}.{hint} Known: {', '.join(known)}.")


def _sizes(value, n: int, name: str, what: str) -> np.ndarray:
    """One finite real number, or `n` of them, as an (n,) float array."""
    if isinstance(value, (str, bytes, bool, np.bool_)) or value is None:
        raise TypeError(f"perturb[{name!r}] must be a number or {n} numbers, got {value!r}.")
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(
            f"perturb[{name!r}] must be a number or {n} numbers, got {value!r}."
        ) from None
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(
            f"perturb[{name!r}] must be one number or one per {what} ({n}), got {value!r}."
        )
    if not np.isfinite(a).all():
        raise ValueError(f"perturb[{name!r}] must be finite, got {value!r}.")
    return a


def _std(value, n: int, name: str, what: str) -> np.ndarray:
    a = _sizes(value, n, name, what)
    if (a < 0).any():
        raise ValueError(f"perturb[{name!r}] is a standard deviation: >= 0, got {value!r}.")
    return a


def _positive(push: Mapping, key: str, default, zero_ok: bool = False) -> float:
    v = push.get(key, default)
    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
    if not ok or not (v >= 0 if zero_ok else v > 0):
        bound = ">= 0" if zero_ok else "> 0"
        raise ValueError(f"perturb['push'][{key!r}] must be a finite number {bound}, got {v!r}.")
    return float(v)


@dataclass(frozen=True)
class Push:
    """Random pushes (see the module docstring): magnitude `force` (N), mean interval
    `every` (s), `periods` control periods each, on model point `point` (index `index`,
    `dims` Cartesian components)."""

    force: float
    every: float
    periods: int
    point: str
    index: int
    dims: int


@dataclass(frozen=True)
class Perturbations:
    """A checked `perturb=` declaration: sizes per feature or input (None: that
    perturbation is off)."""

    obs_noise: np.ndarray | None = None
    action_noise: np.ndarray | None = None
    motor_k: np.ndarray | None = None
    delay: int = 0
    push: Push | None = None

    @classmethod
    def parse(cls, value, plant) -> Perturbations | None:
        """The `perturb` option of an env on `plant`, checked (None or {}: None, off)."""
        if value is None:
            return None
        if not isinstance(value, Mapping):
            raise TypeError(f"perturb must be a dict (keys {', '.join(KEYS)}), got {value!r}.")
        if not value:
            return None
        _unknown(value, KEYS, "perturb")
        n_a, n_obs = len(plant.actuated), plant.obs_size
        out = {}
        if "obs_noise" in value:
            out["obs_noise"] = _std(value["obs_noise"], n_obs, "obs_noise", "observation feature")
        if "action_noise" in value:
            out["action_noise"] = _std(value["action_noise"], n_a, "action_noise", "actuated input")
        if "motor_k" in value:
            k = _sizes(value["motor_k"], n_a, "motor_k", "actuated input")
            if not ((k > 0) & (k <= 2)).all():
                raise ValueError(
                    f"perturb['motor_k'] must lie in (0, 2], got {value['motor_k']!r}."
                )
            out["motor_k"] = k
        if "delay" in value:
            d = value["delay"]
            if not isinstance(d, numbers.Integral) or isinstance(d, bool) or d < 0:
                raise ValueError(
                    f"perturb['delay'] must be an int >= 0 (control periods), got {d!r}."
                )
            out["delay"] = int(d)
        if "push" in value:
            out["push"] = _push(value["push"], plant)
        return cls(**out)


def _push(value, plant) -> Push:
    if not isinstance(value, Mapping):
        raise TypeError(
            f"perturb['push'] must be a dict (keys {', '.join(PUSH_KEYS)}), got {value!r}."
        )
    _unknown(value, PUSH_KEYS, "perturb['push']")
    if "force" not in value:
        raise ValueError("perturb['push'] needs 'force': the magnitude of a push, N.")
    system = plant.system
    points = system.points
    if not points:
        raise ValueError(
            f"perturb['push']: {system.name} declares no points to push (ModelSpec.points)."
        )
    point = value.get("point", next(iter(points)))
    if point not in points:
        close = difflib.get_close_matches(str(point), list(points), n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(
            f"perturb['push']['point'] = {point!r} is not a point of {system.name}.{hint} "
            f"Known: {', '.join(points)}."
        )
    force = _positive(value, "force", None, zero_ok=True)
    every = _positive(value, "every", 2.0)
    duration = _positive(value, "duration", 0.1)
    periods = max(1, round(duration / plant.control_period))
    return Push(force, every, periods, point, list(points).index(point), points[point])


class Perturber:
    """The perturbations' state of N copies: delay lines, motor states, pushes and each
    copy's random numbers. `reseed` at a reset, `inputs` before a step, `observe` after."""

    def __init__(self, spec: Perturbations, plant, n: int):
        self.spec, self.plant, self.n = spec, plant, n
        n_a = len(plant.actuated)
        self.low, self.high = plant.input_low, plant.input_high
        self.u_prev = np.zeros((n, n_a))
        self.queue = np.zeros((n, spec.delay, n_a))
        self.head = 0
        push = spec.push
        self.dims = 0 if push is None else push.dims
        self.force = np.zeros((n, self.dims))  # the push acting on each copy, N
        self.left = np.zeros(n, dtype=np.int64)  # control periods it still acts
        if push is not None:
            self.chance = -math.expm1(-plant.control_period / push.every)  # a start per period
            self.P = np.tile(plant.system.kernels()[1], (n, 1))  # the env's parameters
            self.W = np.zeros((n, plant.system.n_q))
        # each record: action noise, observation noise, a push's direction and its start
        self._cols = {}
        width = 0
        for name, size in (("action", n_a if spec.action_noise is not None else 0),
                           ("obs", plant.obs_size if spec.obs_noise is not None else 0),
                           ("direction", self.dims)):  # fmt: skip
            self._cols[name] = slice(width, width + size)
            width += size
        self.width = width
        self.rngs = [np.random.default_rng() for _ in range(n)]
        self.normal = np.zeros((n, BUFFER, width))
        self.uniform = np.zeros((n, BUFFER, 1 if push else 0))
        self.cursor = np.full(n, BUFFER, dtype=np.int64)
        self._all = np.arange(n)
        self._record = np.zeros((n, width))
        self._start = np.zeros((n, self.uniform.shape[2]))

    # ---- random numbers ----------------------------------------------------------------
    def reseed(self, rows, rngs) -> None:
        """Rows `rows` draw from now on from generators spawned from `rngs` (their reset
        generators, which are left as they were), their state cleared."""
        for i, rng in zip(rows, rngs):
            try:
                self.rngs[i] = rng.spawn(1)[0]
            except (TypeError, AttributeError):  # a bit generator without a seed sequence
                self.rngs[i] = np.random.default_rng(rng.bit_generator.random_raw())
        self.cursor[rows] = BUFFER

    def _draw(self, rows) -> None:
        """The next record of the copies `rows` (an index array) into `_record`, `_start`."""
        for i in rows[self.cursor[rows] >= BUFFER]:
            rng = self.rngs[i]
            self.normal[i] = rng.standard_normal((BUFFER, self.width))
            if self.uniform.shape[2]:
                self.uniform[i] = rng.random((BUFFER, 1))
            self.cursor[i] = 0
        self._record[rows] = self.normal[rows, self.cursor[rows]]
        self._start[rows] = self.uniform[rows, self.cursor[rows]]
        self.cursor[rows] += 1

    # ---- the three hooks ---------------------------------------------------------------
    def clear(self, rows) -> None:
        """Rows start afresh: no command in the delay line, the motor at 0, no push."""
        self.u_prev[rows] = 0.0
        self.queue[rows] = 0.0
        self.force[rows] = 0.0
        self.left[rows] = 0

    def inputs(self, U: np.ndarray, actuated: np.ndarray) -> None:
        """Draw this step's record; replace the commanded inputs U[:, actuated] by the
        applied ones: delayed, through the motor response, noisy, clipped."""
        self._draw(self._all)
        spec = self.spec
        u = U[:, actuated]
        if spec.delay:  # the command of `delay` steps ago comes out, this one goes in
            oldest = self.queue[:, self.head].copy()
            self.queue[:, self.head] = u
            self.head = (self.head + 1) % spec.delay
            u = oldest
        if spec.motor_k is not None:
            k = spec.motor_k  # k = 1 is no response at all: u exactly
            u = np.where(k == 1.0, u, self.u_prev + k * (u - self.u_prev))
            self.u_prev = u
        if spec.action_noise is not None:
            u = u + spec.action_noise * self._record[:, self._cols["action"]]
        U[:, actuated] = np.clip(u, self.low, self.high)

    def pushes(self, T: np.ndarray, X: np.ndarray, P: np.ndarray | None) -> np.ndarray | None:
        """The generalised forces (N, n_q) of the pushes acting over this step, at the
        states X and each row's parameters P (None: the env's), after starting new ones
        with this step's record; None without pushes."""
        push = self.spec.push
        if push is None:
            return None
        idle = self.left == 0
        self.force[idle] = 0.0
        start = idle & (self._start[:, 0] < self.chance)
        if start.any():
            d = self._record[start, self._cols["direction"]]
            self.force[start] = push.force * d / np.linalg.norm(d, axis=1, keepdims=True)
            self.left[start] = push.periods
        self.left[self.left > 0] -= 1  # this step is one of the push's periods
        module = self.plant.system.kernels()[0]
        module.point_forces_batch(T, X, self.P if P is None else P, push.index, self.force, self.W)
        return self.W

    def observe(self, obs64: np.ndarray, O: np.ndarray, rows=None) -> None:
        """O[rows] = the observations obs64[rows] with noise, clipped into their bounds;
        rows given (an index array, at a reset): they take a new record first. None: every
        row, with the record of this step."""
        if rows is None:
            rows = self._all
        else:
            self._draw(rows)
        std = self.spec.obs_noise
        if std is None:
            return
        noisy = obs64[rows] + std * self._record[rows, self._cols["obs"]]
        O[rows] = np.clip(noisy, self.plant.obs_low, self.plant.obs_high)
