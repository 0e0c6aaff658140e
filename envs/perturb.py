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

A perturbed env steps through a variant of the fused step (`envs.fused`) that takes the
applied inputs and the pushes' generalised forces, and the perturbations' own work per
step is one compiled kernel (`_step`): benchmarks/env_speed.py --perturb measures the cost.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numba import njit

from dynamics.checks import did_you_mean

KEYS = ("obs_noise", "action_noise", "motor_k", "delay", "push")
PUSH_KEYS = ("force", "every", "duration", "point")
BUFFER = 64
"""Records of random numbers drawn at a time by each copy's generator (one per reset or
step): a Python call per copy and step would cost more than the step at N = 1024."""


def _unknown(keys, known, where: str) -> None:
    for key in keys:
        if key not in known:
            raise ValueError(
                f"Unknown key {key!r} in {where}.{did_you_mean(key, known)} "
                f"Known: {', '.join(known)}."
            )


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
            if d > plant.task.max_episode_steps:
                raise ValueError(
                    f"perturb['delay'] = {d} control periods is longer than an episode "
                    f"({plant.task.max_episode_steps}): no command would ever act."
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
        raise ValueError(
            f"perturb['push']['point'] = {point!r} is not a point of {system.name}."
            f"{did_you_mean(point, points)} "
            f"Known: {', '.join(points)}."
        )
    force = _positive(value, "force", None, zero_ok=True)
    every = _positive(value, "every", 2.0)
    duration = _positive(value, "duration", 0.1)
    longest = plant.task.max_episode_steps * plant.control_period
    if duration > longest:
        raise ValueError(
            f"perturb['push']['duration'] = {duration:g} s is longer than an episode "
            f"({longest:g} s): give at most that (a push lasting the whole episode)."
        )
    periods = max(1, round(duration / plant.control_period))
    return Push(force, every, periods, point, list(points).index(point), points[point])


class Perturber:
    """The perturbations' state of N copies: delay lines, motor states, pushes and each
    copy's random numbers. `reseed` at a reset, `before_step`, then `observe` after it."""

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
        self.applied = np.zeros((n, n_a))  # the inputs of the last step
        self.W = np.zeros((n, 0 if push is None else plant.system.n_q))  # its pushes
        # the chance that a push starts in a control period without one
        self.chance = 0.0 if push is None else -math.expm1(-plant.control_period / push.every)
        # each record: action noise, observation noise, a push's direction and its start
        self._cols = {}
        width = 0
        for name, size in (
            ("action", n_a if spec.action_noise is not None else 0),
            ("obs", plant.obs_size if spec.obs_noise is not None else 0),
            ("direction", self.dims),
        ):
            self._cols[name] = slice(width, width + size)
            width += size
        self.width = width
        self.rngs = [np.random.default_rng() for _ in range(n)]
        self.normal = np.zeros((n, BUFFER, width))
        self.uniform = np.zeros((n, BUFFER, 1 if push else 0))
        self.cursor = np.full(n, BUFFER, dtype=np.int64)
        self._all = np.arange(n)
        # the kernel's arguments for the perturbations that are off
        self.k = np.ones(n_a) if spec.motor_k is None else spec.motor_k
        self.action_std = np.zeros(0) if spec.action_noise is None else spec.action_noise

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

    def _fill(self, rows) -> None:
        """New buffers of random numbers for the copies `rows` (an index array) whose
        buffers are used up."""
        for i in rows[self.cursor[rows] >= BUFFER]:
            rng = self.rngs[i]
            self.normal[i] = rng.standard_normal((BUFFER, self.width))
            if self.uniform.shape[2]:
                self.uniform[i] = rng.random((BUFFER, 1))
            self.cursor[i] = 0

    # ---- the three hooks ---------------------------------------------------------------
    def clear(self, rows) -> None:
        """Rows start afresh: no command in the delay line, the motor at 0, no push."""
        self.u_prev[rows] = 0.0
        self.queue[rows] = 0.0
        self.force[rows] = 0.0
        self.left[rows] = 0

    def before_step(self, actions, T, X, P) -> tuple[np.ndarray, np.ndarray]:
        """(applied, W) for a step under `actions` (N, n_a), finite, from states X at
        times T with each row's parameters P (the runtime's `model_params`, read here):
        the inputs applied to the actuated inputs (N, n_a) and the generalised forces of
        the pushes (N, n_q; (N, 0) without)."""
        if self.cursor.max() >= BUFFER:
            self._fill(self._all)
        spec, plant, push = self.spec, self.plant, self.spec.push
        _step(
            actions,
            plant.input_mid,
            plant.input_half,
            self.low,
            self.high,
            self.queue,
            self.head,
            self.k,
            self.u_prev,
            self.action_std,
            self.normal,
            self.uniform,
            self.cursor,
            self._cols["action"].start,
            self._cols["direction"].start,
            self.chance,
            0.0 if push is None else push.force,
            0 if push is None else push.periods,
            self.force,
            self.left,
            self.applied,
        )
        if spec.delay:
            self.head = (self.head + 1) % spec.delay
        if push is not None:
            plant.system.kernel_module.point_forces_batch(T, X, P, push.index, self.force, self.W)
        return self.applied, self.W

    def observe(self, obs64: np.ndarray, O: np.ndarray, rows=None) -> None:
        """O[rows] = the observations obs64[rows] with noise, clipped into their bounds;
        rows given (an index array, at a reset): they take a new record first. None: every
        row, with the record of this step."""
        if rows is None:
            rows = self._all
        else:
            self._fill(rows)
            self.cursor[rows] += 1
        if self.spec.obs_noise is None:
            return
        _observe(
            obs64,
            O,
            rows,
            self.spec.obs_noise,
            self.normal,
            self.cursor,
            self._cols["obs"].start,
            self.plant.obs_low,
            self.plant.obs_high,
        )


@njit(cache=True)
def _step(
    actions,
    mid,
    half,
    low,
    high,
    queue,
    head,
    k,
    u_prev,
    std,
    normal,
    uniform,
    cursor,
    a0,
    d0,
    chance,
    size,
    periods,
    force,
    left,
    applied,
) -> None:
    """Each row's next record (at cursor, then advanced); its commanded inputs (the clipped
    actions as inputs) through the delay line (the oldest out at `head`, the new one in),
    the motor response (k = 1: none), the noise std (none if empty) and the limits into
    `applied`; and where no push acts, a new one with chance `chance`: `size` along the
    record's direction (from column d0), for `periods` steps (`left` counts this one)."""
    for b in range(actions.shape[0]):
        c = cursor[b]
        for j in range(actions.shape[1]):
            a = min(max(actions[b, j], -1.0), 1.0)
            u = mid[j] + a * half[j]
            if queue.shape[1]:
                u, queue[b, head, j] = queue[b, head, j], u
            if k[j] != 1.0:
                u = u_prev[b, j] + k[j] * (u - u_prev[b, j])
            u_prev[b, j] = u
            if std.shape[0]:
                u = u + std[j] * normal[b, c, a0 + j]
            applied[b, j] = min(max(u, low[j]), high[j])
        if force.shape[1]:
            if left[b] == 0:
                force[b, :] = 0.0
                if uniform[b, c, 0] < chance:
                    norm = 0.0
                    for i in range(force.shape[1]):
                        norm += normal[b, c, d0 + i] ** 2
                    norm = math.sqrt(norm)
                    for i in range(force.shape[1]):
                        force[b, i] = size * normal[b, c, d0 + i] / norm
                    left[b] = periods
            if left[b] > 0:
                left[b] -= 1
        cursor[b] = c + 1


@njit(cache=True)
def _observe(obs64, O, rows, std, normal, cursor, o0, low, high) -> None:
    """O[r] = obs64[r] plus the noise std times the record last taken (from column o0),
    clipped into [low, high], for each row r in rows."""
    for r in rows:
        c = cursor[r] - 1
        for j in range(obs64.shape[1]):
            v = obs64[r, j] + std[j] * normal[r, c, o0 + j]
            O[r, j] = min(max(v, low[j]), high[j])
