"""The shared machinery of every Lagrange environment: `LagrangianEnv` and its native
`LagrangianVectorEnv`.

An environment is a compiled `dynamics.System` plus a task. The base class owns everything
that is not the task: building the system from keyword arguments, mapping actions in
[-1, 1] to physical torques, fixed-step RK4 through the compiled kernel, divergence
handling, `info`, seeding and resets, pickling and rendering.

A task subclass supplies what is particular to it. Per step, one compiled (numba) kernel
evaluates every copy: `evaluate(X, A, G, Y, c, obs, terms, flags)` writes, for each row of
states X (N, 2n), clipped actions A (N, n_a) and goals G (N, n_g), the observation, the
reward terms (summed into the reward, named by `reward_names`, on the post-step state) and
flags [terminated, success]; Y holds the model's outputs (`System.outputs`, columns in the
order of `system.output_names`) if the task sets `uses_outputs`, and `c` the task's
constants (`_task_constants`). A Python
loop of numpy calls per step would cost several times the RK4 step itself. Off the hot path,
plain numpy methods: `_sample_start(rng) -> (x, goal)`, `_state_from_observation(obs)`,
`_goal_from_observation(obs)`, `_operating_state(goal, x)` (x: the current states, for
tasks with several operating points per goal), `_observation_high()`,
`_state_limits()` (divergence bounds on |x|), and `_draw(surface, x, goal, history)` for
rendering through `envs.rendering` (history: the states of the frames rendered so far this
episode, or None). The vector env runs the same kernels on all its copies at once.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numba import njit

import dynamics

from . import rendering

ANGLE_LIMIT = 1e9
"""Divergence bound on |angle| (angles are observed through cos/sin; only overflow matters)."""


@njit(cache=True)
def wrap(a: float) -> float:
    """An angle wrapped to [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


@njit(cache=True)
def apply_actions(actions, max_torque, actuated, clipped, U) -> bool:
    """Clip actions to [-1, 1] into `clipped` and scale them into the actuated columns of
    the input rows U; False (and nothing written) if any action is NaN or inf."""
    for b in range(actions.shape[0]):
        for j in range(actions.shape[1]):
            if not np.isfinite(actions[b, j]):
                return False
    for b in range(actions.shape[0]):
        for j in range(actions.shape[1]):
            a = min(max(actions[b, j], -1.0), 1.0)
            clipped[b, j] = a
            U[b, actuated[j]] = a * max_torque[j]
    return True


@njit(cache=True)
def check_states(X, X_prev, limits, diverged) -> bool:
    """diverged[b] = some |X[b, i]| > limits[i] or non-finite; a non-finite row is put
    back to its previous (finite) state. Returns whether any row diverged."""
    any_bad = False
    for b in range(X.shape[0]):
        bad = False
        finite = True
        for i in range(X.shape[1]):
            v = X[b, i]
            if not np.isfinite(v):
                finite = False
                bad = True
            elif abs(v) > limits[i]:
                bad = True
        if not finite:
            for i in range(X.shape[1]):
                X[b, i] = X_prev[b, i]
        diverged[b] = bad
        any_bad |= bad
    return any_bad


@njit(cache=True)
def sum_rows(terms, out) -> None:
    """out[b] = the sum of the reward terms of row b, left to right."""
    for b in range(terms.shape[0]):
        r = 0.0
        for k in range(terms.shape[1]):
            r += terms[b, k]
        out[b] = r


class LagrangianEnv(gym.Env):
    """Base of the Lagrange environments (see the module docstring for the task hooks).

    Keyword arguments: `control_period` (s), `substeps` (RK4 steps per control period),
    `max_torque` (physical limit of each action component, scalar or sequence),
    `render_mode`, and any parameter of the model by name (SI units).
    """

    # ---- what a task declares ------------------------------------------------------
    model: ClassVar[str]
    actuated: ClassVar[tuple[int, ...]]  # model inputs driven by the action, in order
    default_control_period: ClassVar[float] = 0.05
    default_substeps: ClassVar[int] = 10
    default_max_torque: ClassVar[tuple[float, ...]]
    goal_size: ClassVar[int]
    reward_names: ClassVar[tuple[str, ...]]
    evaluate: ClassVar[Any]  # the task's numba kernel (see the module docstring)
    uses_outputs: ClassVar[bool] = False  # evaluate reads the model's outputs Y
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"]}

    def __init__(
        self,
        render_mode: str | None = None,
        control_period: float | None = None,
        substeps: int | None = None,
        max_torque: float | np.ndarray | None = None,
        **params: float,
    ):
        self.system = _compile(type(self), self.model, params)
        self.periodic: tuple[bool, ...] = self._periodic()
        self.control_period = _positive_float(
            "control_period",
            self.default_control_period if control_period is None else control_period,
        )
        self.substeps = _positive_int(
            "substeps", self.default_substeps if substeps is None else substeps
        )
        n_a = len(self.actuated)
        if max_torque is None:
            max_torque = self._default_max_torque()
        self.max_torque = _torque_limits(max_torque, n_a)
        fps = max(1, round(1.0 / self.control_period))
        self.metadata = {**type(self).metadata, "render_fps": fps}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}."
            )
        self.render_mode = render_mode
        self.action_space = spaces.Box(-1.0, 1.0, (n_a,), np.float32)
        self._action_shape = (n_a,)
        self._actuated = np.array(self.actuated, dtype=np.int64)
        high = self._observation_high().astype(np.float32)
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        self._limits = np.ascontiguousarray(self._state_limits(), dtype=np.float64)
        self._c = np.ascontiguousarray(self._task_constants(), dtype=np.float64)
        self._init_buffers(1)
        self._viewer: rendering.Viewer | None = None
        self._history = []

    # ---- construction helpers ------------------------------------------------------
    def _periodic(self) -> tuple[bool, ...]:
        """True for the coordinates that are angles (override per task)."""
        return tuple(False for _ in range(self.system.n_q))

    def _task_constants(self) -> np.ndarray:
        """Constants the task kernel reads (override per task)."""
        return np.zeros(1)

    def _default_max_torque(self) -> np.ndarray:
        return np.asarray(self.default_max_torque, dtype=np.float64)

    def _init_buffers(self, n: int) -> None:
        s = self.system
        self._X = np.zeros((n, s.state_size))
        self._X_next = np.zeros((n, s.state_size))
        self._U = np.zeros((n, s.n_u))
        self._T = np.zeros(n)
        self._G = np.zeros((n, self.goal_size))
        self._E = np.zeros((n, 2))
        self._C = np.zeros((n, s.n_c))
        self._A = np.zeros((n, len(self.actuated)))  # clipped actions
        self._O = np.zeros((n,) + self.observation_space.shape, dtype=np.float32)
        self._Q = np.zeros((n, len(self.reward_names)))  # reward terms
        self._R = np.zeros(n)  # rewards
        self._F = np.zeros((n, 2), dtype=np.bool_)  # terminated, success
        self._D = np.zeros(n, dtype=np.bool_)  # diverged
        self._Y = np.zeros((n, len(s.output_names) if self.uses_outputs else 0))
        self._energy_kernel, self._residual_kernel, self._outputs_kernel = _kernels(s)
        self._ready = False

    # ---- the contract --------------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        """Physical state x = [q, qdot] (copy), float64 (2n,)."""
        return self._X[0].copy()

    @property
    def goal(self) -> np.ndarray:
        """The current goal or command (copy)."""
        return self._G[0].copy()

    def action_to_input(self, action) -> np.ndarray:
        """Model input vector u for `action` (clipped to [-1, 1]); batched over leading axes."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        u = np.zeros(a.shape[:-1] + (self.system.n_u,))
        u[..., list(self.actuated)] = a * self.max_torque
        return u

    def input_to_action(self, u) -> np.ndarray:
        """The action that applies model input u (unclipped inverse of `action_to_input`)."""
        u = np.asarray(u, dtype=np.float64)
        return u[..., list(self.actuated)] / self.max_torque

    def state_from_observation(self, obs) -> np.ndarray:
        """Physical state x recovered from observations (batched over leading axes)."""
        obs = np.asarray(obs, dtype=np.float64)
        return self._state_from_observation(obs.reshape(-1, obs.shape[-1])).reshape(
            obs.shape[:-1] + (self.system.state_size,)
        )

    def goal_from_observation(self, obs) -> np.ndarray:
        """The goal or command encoded in observations (batched over leading axes)."""
        obs = np.asarray(obs, dtype=np.float64)
        return self._goal_from_observation(obs.reshape(-1, obs.shape[-1])).reshape(
            obs.shape[:-1] + (self.goal_size,)
        )

    def operating_point(self, obs=None) -> tuple[np.ndarray, np.ndarray]:
        """(x0, u0): the state and model inputs the task regulates to, for the current goal
        or for the goal encoded in `obs` (batched if obs is)."""
        if obs is None:
            goal, x = self._G[:1], self._X[:1]
            lead: tuple[int, ...] = ()
        else:
            obs = np.asarray(obs, dtype=np.float64)
            lead = obs.shape[:-1]
            rows = obs.reshape(-1, obs.shape[-1])
            goal, x = self._goal_from_observation(rows), self._state_from_observation(rows)
        x0 = self._operating_state(goal, x)
        u0 = self._operating_input(x0)
        return x0.reshape(lead + x0.shape[-1:]), u0.reshape(lead + u0.shape[-1:])

    def _operating_input(self, x0: np.ndarray) -> np.ndarray:
        """Inputs that hold x0 with zero accelerations (least squares over the actuated
        inputs; accelerations are affine in the inputs, so two evaluations per input give
        the exact input matrix)."""
        s, idx = self.system, list(self.actuated)
        u = np.zeros(x0.shape[:-1] + (s.n_u,))
        a0 = s.accelerations(0.0, x0, u)
        cols = []
        for j in idx:
            e = u.copy()
            e[..., j] = 1.0
            cols.append(s.accelerations(0.0, x0, e) - a0)
        B = np.stack(cols, axis=-1)  # (..., n_q, n_a)
        u[..., idx] = -(np.linalg.pinv(B) @ a0[..., None])[..., 0]
        return u

    # ---- reset / step --------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        x, goal = self._start(self.np_random, options, 0)
        self._X[0] = x
        self._G[0] = goal
        self._T[0] = 0.0
        self._U[:] = 0.0
        self._A[:] = 0.0
        self._ready = True
        self._history: list[np.ndarray] = []  # states of the frames rendered this episode
        self._evaluate()
        if self.render_mode == "human":
            self.render()
        return self._O[0].copy(), self._reset_info(0)

    def _start(self, rng: np.random.Generator, options: dict | None, row: int):
        """Starting state and goal for one copy: sampled, then overridden by options."""
        x, goal = self._sample_start(rng)
        if options:
            unknown = set(options) - {"state", "goal"}
            if unknown:
                raise ValueError(
                    f"Unknown reset option(s) {sorted(unknown)}; known: 'state', 'goal'."
                )
            if options.get("state") is not None:
                x = _row(options["state"], row, (self.system.state_size,), "options['state']")
            if options.get("goal") is not None:
                goal = _row(options["goal"], row, (self.goal_size,), "options['goal']")
                self._check_goal(goal)
        x = np.asarray(x, dtype=np.float64)
        if self.system.n_c:
            x = self.system.project(x)
        return x, np.asarray(goal, dtype=np.float64)

    def _check_goal(self, goal: np.ndarray) -> None:
        """Raise ValueError for a goal the task cannot take (override per task)."""

    def step(self, action):
        if not self._ready:
            raise RuntimeError("Call reset() before step().")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self._action_shape:
            raise ValueError(f"Expected action of shape {self._action_shape}, got {a.shape}.")
        if not apply_actions(
            a.reshape(self._A.shape), self.max_torque, self._actuated, self._A, self._U
        ):
            raise ValueError(f"Action contains NaN or inf: {action!r}.")
        self.system.step_unchecked(
            self._T, self._X, self._U, self.control_period, self.substeps, self._X_next
        )
        self._X, self._X_next = self._X_next, self._X
        self._T += self.control_period
        diverged = bool(check_states(self._X, self._X_next, self._limits, self._D))
        self._evaluate()
        if diverged:
            np.clip(self._O, self.observation_space.low, self.observation_space.high, out=self._O)
        info = self._step_info(diverged)
        if self.render_mode == "human":
            self.render()
        return self._O[0].copy(), float(self._R[0]), bool(self._F[0, 0]), diverged, info

    def _evaluate(self) -> None:
        """Observation, reward terms, reward and [terminated, success] of every row."""
        if self.uses_outputs:
            self._outputs_kernel(self._T, self._X, self._U, self._Y)
        self.evaluate(self._X, self._A, self._G, self._Y, self._c, self._O, self._Q, self._F)
        sum_rows(self._Q, self._R)

    def _step_info(self, diverged: bool) -> dict[str, Any]:
        self._energy_kernel(self._T, self._X, self._E)
        info = {
            "state": self._X[0].copy(),
            "input": self._U[0].copy(),
            "energy": float(self._E[0, 0] + self._E[0, 1]),
            "reward_terms": dict(zip(self.reward_names, self._Q[0].tolist())),
            "is_success": bool(self._F[0, 1]),
            "diverged": diverged,
        }
        if self.system.n_c:
            self._residual_kernel(self._T, self._X, self._C)
            info["constraint_residual"] = self._C[0].copy()
        return info

    def _reset_info(self, row: int) -> dict[str, Any]:
        X, T = self._X[row : row + 1], self._T[row : row + 1]
        self._energy_kernel(T, X, self._E[:1])
        info = {
            "state": X[0].copy(),
            "input": np.zeros(self.system.n_u),
            "energy": float(self._E[0].sum()),
            "goal": self._G[row].copy(),
        }
        if self.system.n_c:
            self._residual_kernel(T, X, self._C[:1])
            info["constraint_residual"] = self._C[0].copy()
        return info

    # ---- rendering -----------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "render() was called without a render_mode; pass render_mode='rgb_array' "
                "or 'human' to gymnasium.make."
            )
            return None
        if self._viewer is None:
            self._viewer = rendering.Viewer(self.render_mode, self.metadata["render_fps"])
        self._history.append(self._X[0].copy())
        return self._viewer.show(
            lambda surface: self._draw(surface, self._X[0], self._G[0], self._history)
        )

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    # ---- pickling: the System rebuilds from its cache; a pygame window does not travel
    def __getstate__(self):
        state = self.__dict__.copy()
        state["_viewer"] = None
        for k in ("_energy_kernel", "_residual_kernel", "_outputs_kernel"):
            state.pop(k)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._energy_kernel, self._residual_kernel, self._outputs_kernel = _kernels(self.system)


class LagrangianVectorEnv(VectorEnv):
    """`num_envs` copies of a `LagrangianEnv` stepped in one call of the compiled system.

    Gymnasium 1.x next-step autoreset: a copy that terminated or was truncated is reset by
    the following `step` (its action is ignored, reward 0). Each copy has its own random
    generator, seeded `seed + i` as `SyncVectorEnv` seeds its envs, so copy i reproduces a
    single env reset with `seed + i` bit for bit. Episodes are truncated after
    `max_episode_steps` (from the registry) here, not by a wrapper.
    """

    env_class: ClassVar[type[LagrangianEnv]]
    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ):
        self.num_envs = _positive_int("num_envs", num_envs)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"The vector env renders only 'rgb_array', got {render_mode!r}.")
        self.render_mode = render_mode
        self.max_episode_steps = (
            None
            if max_episode_steps is None
            else _positive_int("max_episode_steps", max_episode_steps)
        )
        env = self.env_class(**kwargs)
        env._init_buffers(self.num_envs)
        self._env = env
        self.metadata = {**type(self).metadata, "render_fps": env.metadata["render_fps"]}
        self.single_action_space = env.action_space
        self.single_observation_space = env.observation_space
        self.action_space = batch_space(env.action_space, self.num_envs)
        self.observation_space = batch_space(env.observation_space, self.num_envs)
        self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._done = np.zeros(self.num_envs, dtype=bool)
        self._ready = False
        self._viewer = None

    # the contract, shared with the single env
    system = property(lambda self: self._env.system)
    control_period = property(lambda self: self._env.control_period)
    substeps = property(lambda self: self._env.substeps)
    max_torque = property(lambda self: self._env.max_torque)
    periodic = property(lambda self: self._env.periodic)

    @property
    def state(self) -> np.ndarray:
        """Physical states, float64 (num_envs, 2n) (copy)."""
        return self._env._X.copy()

    @property
    def goal(self) -> np.ndarray:
        return self._env._G.copy()

    def action_to_input(self, action) -> np.ndarray:
        return self._env.action_to_input(action)

    def input_to_action(self, u) -> np.ndarray:
        return self._env.input_to_action(u)

    def state_from_observation(self, obs) -> np.ndarray:
        return self._env.state_from_observation(obs)

    def goal_from_observation(self, obs) -> np.ndarray:
        return self._env.goal_from_observation(obs)

    def operating_point(self, obs=None) -> tuple[np.ndarray, np.ndarray]:
        """(x0, u0) per copy, for the current goals or those encoded in `obs`."""
        env = self._env
        if obs is None:
            x0 = env._operating_state(env._G, env._X)
            return x0, env._operating_input(x0)
        return env.operating_point(obs)

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        if seed is not None:
            seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else seed
            if len(seeds) != self.num_envs:
                raise ValueError(f"Expected {self.num_envs} seeds, got {len(seeds)}.")
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        env = self._env
        for i in range(self.num_envs):
            env._X[i], env._G[i] = env._start(self._rngs[i], options, i)
        env._T[:] = 0.0
        env._U[:] = 0.0
        env._A[:] = 0.0
        self._steps[:] = 0
        self._done[:] = False
        self._ready = True
        env._evaluate()
        return env._O.copy(), self._info(None)

    def step(self, actions):
        if not self._ready:
            raise RuntimeError("Call reset() before step().")
        env = self._env
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"Expected actions of shape {self.action_space.shape}, got {a.shape}.")
        if not apply_actions(a, env.max_torque, env._actuated, env._A, env._U):
            rows = np.flatnonzero(~np.isfinite(a).all(axis=1))
            raise ValueError(f"Actions contain NaN or inf (envs {rows.tolist()}).")
        env.system.step_unchecked(
            env._T, env._X, env._U, env.control_period, env.substeps, env._X_next
        )
        env._X, env._X_next = env._X_next, env._X
        env._T += env.control_period
        self._steps += 1
        any_diverged = check_states(env._X, env._X_next, env._limits, env._D)
        reset = self._done
        if reset.any():
            for i in np.flatnonzero(reset):
                env._X[i], env._G[i] = env._start(self._rngs[i], None, i)
            env._T[reset] = 0.0
            env._U[reset] = 0.0
            env._A[reset] = 0.0
            self._steps[reset] = 0
            env._D[reset] = False
        env._evaluate()
        if any_diverged:
            np.clip(env._O, env.observation_space.low, env.observation_space.high, out=env._O)
        env._Q[reset] = 0.0
        env._R[reset] = 0.0
        terminated = env._F[:, 0] & ~reset
        truncated = env._D.copy()
        if self.max_episode_steps is not None:
            truncated |= self._steps >= self.max_episode_steps
        self._done = terminated | truncated
        return env._O.copy(), env._R.copy(), terminated, truncated, self._info(env._D)

    def _info(self, diverged: np.ndarray | None) -> dict[str, Any]:
        env = self._env
        env._energy_kernel(env._T, env._X, env._E)
        every = np.ones(self.num_envs, dtype=bool)
        info: dict[str, Any] = {
            "state": env._X.copy(),
            "input": env._U.copy(),
            "energy": env._E.sum(axis=1),
        }
        if diverged is not None:
            terms = {k: env._Q[:, i].copy() for i, k in enumerate(env.reward_names)}
            info["reward_terms"] = {**terms, **{"_" + k: every for k in terms}}
            info["is_success"] = env._F[:, 1].copy()
            info["diverged"] = diverged.copy()
        else:
            info["goal"] = env._G.copy()
        if env.system.n_c:
            env._residual_kernel(env._T, env._X, env._C)
            info["constraint_residual"] = env._C.copy()
        info.update({"_" + k: every for k in list(info)})
        return info

    def render(self):
        """rgb_array frames of every copy (a tuple), like Gymnasium's native vector envs."""
        if self.render_mode is None:
            gym.logger.warn("render() was called without render_mode='rgb_array'.")
            return None
        env = self._env
        if self._viewer is None:
            self._viewer = rendering.Viewer("rgb_array", self.metadata["render_fps"])
        return tuple(
            self._viewer.show(lambda s, i=i: env._draw(s, env._X[i], env._G[i], None))
            for i in range(self.num_envs)
        )

    def close_extras(self, **kwargs: Any) -> None:
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_viewer"] = None
        return state


# ---- helpers ---------------------------------------------------------------------------
_ENV_OPTIONS = ("render_mode", "control_period", "substeps", "max_torque")


def _compile(cls: type, model: str, params: dict) -> dynamics.System:
    """The compiled model with `params`, or an error naming the closest known keyword."""
    system = dynamics.get_model(model).compile()
    known = list(system.parameters)
    for key in params:
        if key not in known:
            close = difflib.get_close_matches(key, known + list(_ENV_OPTIONS), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(
                f"Unknown argument {key!r} for {cls.__name__}.{hint} Known: "
                f"{', '.join(_ENV_OPTIONS)} and the parameters of {model}: {', '.join(known)}."
            )
    return system.with_parameters(**params) if params else system


def _kernels(system: dynamics.System):
    """`System`'s unchecked energy, residual and outputs, to call on the env's own
    contiguous buffers (the checked methods would cost more than the RK4 step)."""
    return (
        system.energy_terms_unchecked,
        system.constraint_residual_unchecked,
        system.outputs_unchecked,
    )


def _positive_float(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {value!r}.") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    return v


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}.")
    if value < 1:
        raise ValueError(f"{name} must be at least 1, got {value}.")
    return int(value)


def _torque_limits(value, n: int) -> np.ndarray:
    try:
        limits = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
    except (TypeError, ValueError):
        raise ValueError(
            f"max_torque must be a number or a sequence of {n} numbers, got {value!r}."
        ) from None
    if not (np.isfinite(limits).all() and (limits > 0).all()):
        raise ValueError(f"max_torque must be positive and finite, got {value!r}.")
    return limits


def _row(value, row: int, shape: tuple[int, ...], name: str) -> np.ndarray:
    """`value` for copy `row`: either one value of `shape` shared by all, or a batch."""
    v = np.asarray(value, dtype=np.float64)
    if v.ndim == len(shape) + 1:
        if row >= v.shape[0]:
            raise ValueError(f"{name} has {v.shape[0]} rows; copy {row} has none.")
        v = v[row]
    if v.shape != shape:
        raise ValueError(f"Expected {name} of shape {shape}, got {np.shape(value)}.")
    if not np.isfinite(v).all():
        raise ValueError(f"{name} contains NaN or inf: {v}.")
    return v.copy()
