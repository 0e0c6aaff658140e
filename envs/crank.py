"""Lagrange/CrankSlider-v0: move the slider of problem 7/3 to a target position and hold it."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import rendering
from .base import ANGLE_LIMIT, LagrangianEnv, LagrangianVectorEnv

RATE_LIMIT = 40 * np.pi
"""Bound on |theta'| (rad/s): observation bound; beyond it the episode diverged."""
TARGET_MARGIN = 0.1
"""Targets stay this fraction of the slider's travel away from its ends."""
POSITION_TOLERANCE = 0.02
"""Success: |x - x*| below this fraction of the travel ..."""
RATE_TOLERANCE = 0.2
"""... and |theta'| below this (rad/s)."""
GRID = 720
"""Crank angles sampled to find the slider's travel and to bracket target angles."""


@njit(cache=True)
def evaluate(X, A, G, Y, c, obs, terms, flags):
    """Observation, reward terms (distance, rate, effort), [terminated, success] per row.
    Y: the model's outputs; c = [column of slider_x, column of slider_v, half the travel]."""
    ix, iv, half = int(c[0]), int(c[1]), c[2]
    for b in range(X.shape[0]):
        theta, w = X[b, 0], X[b, 1]
        x, v = Y[b, ix], Y[b, iv]
        obs[b, 0] = math.cos(theta)
        obs[b, 1] = math.sin(theta)
        obs[b, 2] = w
        obs[b, 3] = x
        obs[b, 4] = v
        obs[b, 5] = G[b, 0]
        e = (x - G[b, 0]) / half
        terms[b, 0] = -e * e
        terms[b, 1] = -0.001 * w * w
        terms[b, 2] = -0.001 * A[b, 0] * A[b, 0]
        flags[b, 0] = False
        flags[b, 1] = abs(e) < 2 * POSITION_TOLERANCE and abs(w) < RATE_TOLERANCE


class CrankSliderEnv(LagrangianEnv):
    """
    ## Description
    Problem 7/3 (model `eccentric_disk_slider`): a heavy eccentric disk turns about a fixed
    horizontal axle O; a massless rod PS of length l joins its pin P (at OP = R) to a
    particle S sliding on a smooth horizontal line at depth h below O. A motor drives the
    disk. The task: move the slider to a target position x* and hold it there.

    ```
                  P  (pin, OP = R)
           G    /  \\                  theta: angle of OP from +x, counter-clockwise;
             \\ / th  \\  rod l         G, the disk's mass centre, at s along OP;
               O ------ \\ ----> x     x: the slider's position along its line
               : h        S            (x = R cos theta + sqrt(l^2 - (R sin theta + h)^2)).
       ======================== smooth line
    ```
    Every slider position in the travel is reached at two crank angles (pin above or
    below the line OS); gravity acts on the disk only, so holding the slider needs the
    torque M g s cos(theta).

    ## Action Space
    | Num | Action               | Min | Max | Unit                    |
    |-----|----------------------|-----|-----|-------------------------|
    | 0   | motor torque on disk | -1  | 1   | x `max_torque` (2 N*m)  |

    Clipped to [-1, 1]; NaN or inf raise ValueError. The default disk needs at most
    M g s = 0.98 N*m to hold any position.

    ## Observation Space
    float32, shape (6,): cos theta, sin theta (in [-1, 1]), theta' (rad/s, in
    [-40 pi, 40 pi]), the slider's position x (m) and velocity x' (m/s) (the model's
    outputs `slider_x`, `slider_v`; bounded by the travel and by the largest dx/dtheta
    times the rate bound), and the target x* (m).

    ## Rewards
    On the state after the step, the sum of `distance` = -((x - x*) / (travel / 2))^2,
    `rate` = -0.001 theta'^2 and `effort` = -0.001 action^2.

    ## Starting State
    theta uniform in [-pi, pi), theta' uniform in [-0.5, 0.5] rad/s; x* uniform over the
    travel less 10% at each end. `reset(options={"state": x, "goal": (x*,)})` sets them.

    ## Episode End
    No termination. Truncation: 200 steps (10 s), or divergence (a non-finite state or
    |theta'| > 40 pi rad/s; `info["diverged"]`). `info["is_success"]`: |x - x*| below 2%
    of the travel and |theta'| < 0.2 rad/s.

    ## Arguments
    `gymnasium.make("Lagrange/CrankSlider-v0", control_period=0.05, substeps=10,
    max_torque=2.0, render_mode=None, **model_parameters)` with the parameters of
    `eccentric_disk_slider` by name (I, M, m, s, R, l, h, g). Integration: RK4, 10
    substeps of 5 ms per 50 ms step; an unforced episode keeps the energy within 1e-7 of
    M g |s| (5e-8 measured over 100 episodes, tests/envs/test_physics.py; 5 substeps
    gave 1.4e-6).
    `operating_point(obs)` regulates to rest at the crank angle, of the two that put the
    slider at x*, nearest the current (or observed) crank angle.

    ## Version History
    * v0: initial version.
    """

    model = "eccentric_disk_slider"
    actuated = (0,)
    default_control_period = 0.05
    default_substeps = 10
    default_max_torque = (2.0,)
    goal_size = 1
    reward_names = ("distance", "rate", "effort")
    evaluate = staticmethod(evaluate)
    uses_outputs = True

    def __init__(self, *args, **kwargs):
        self._grid = None
        super().__init__(*args, **kwargs)

    def _slider(self, theta, rate=None):
        """The model's slider position (and velocity) at crank angles theta."""
        theta = np.asarray(theta, dtype=np.float64)
        x = np.stack([theta, np.zeros_like(theta) if rate is None else rate], axis=-1)
        out = self.system.outputs(0.0, x)
        return out["slider_x"], out["slider_v"]

    def _travel(self):
        """Crank-angle grid, slider positions on it, and the largest |dx/dtheta|."""
        if self._grid is None:
            theta = np.linspace(-np.pi, np.pi, GRID, endpoint=False)
            x, dx = self._slider(theta, np.ones_like(theta))
            self._grid = (theta, x, float(np.abs(dx).max()))
        return self._grid

    def _periodic(self):
        return (True,)

    def _task_constants(self) -> np.ndarray:
        names = self.system.output_names
        _, x, _ = self._travel()
        return np.array([names.index("slider_x"), names.index("slider_v"), (x.max() - x.min()) / 2])

    def _observation_high(self) -> np.ndarray:
        _, x, slope = self._travel()
        reach = 1.01 * np.abs(x).max()
        return np.array([1, 1, RATE_LIMIT, reach, 1.01 * slope * RATE_LIMIT, reach])

    def _state_limits(self) -> np.ndarray:
        return np.array([ANGLE_LIMIT, RATE_LIMIT])

    def _target_range(self) -> tuple[float, float]:
        _, x, _ = self._travel()
        lo, hi = x.min(), x.max()
        margin = TARGET_MARGIN * (hi - lo)
        return lo + margin, hi - margin

    def _sample_start(self, rng):
        x = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-0.5, 0.5)])
        return x, np.array([rng.uniform(*self._target_range())])

    def _check_goal(self, goal):
        lo, hi = self._target_range()
        if not lo <= goal[0] <= hi:
            raise ValueError(f"Slider target must lie in [{lo:.4f}, {hi:.4f}] m; got {goal[0]}.")

    def _state_from_observation(self, obs):
        return np.stack([np.arctan2(obs[:, 1], obs[:, 0]), obs[:, 2]], axis=1)

    def _goal_from_observation(self, obs):
        return obs[:, 5:6].copy()

    def _operating_state(self, goal, x):
        """At rest at the crank angle, of the two that put the slider at the target,
        nearest the crank angle of x (its holding torque comes from the base class)."""
        return self._rest_at(goal[:, 0], x[:, 0])

    def _rest_at(self, target, near):
        """States at rest with the slider at `target` (N,), crank angle nearest `near`."""
        grid, x, _ = self._travel()
        roots = []
        for k in range(2):  # the two monotone branches between the dead centres
            f = x[None, :] - target[:, None]
            crossing = (np.sign(f) != np.sign(np.roll(f, -1, axis=1))) & (
                (np.roll(f, -1, axis=1) > f) == bool(k)
            )
            i = crossing.argmax(axis=1)
            lo, hi = grid[i], grid[i] + 2 * np.pi / GRID
            for _ in range(60):  # bisection to round-off: the bracket halves each time
                mid = (lo + hi) / 2
                above = (self._slider(mid)[0] > target) != bool(k)
                lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
            roots.append((lo + hi) / 2)
        roots = np.stack(roots, axis=1)
        pick = np.abs(wrap_array(roots - near[:, None])).argmin(axis=1)
        theta = roots[np.arange(len(target)), pick]
        return np.stack([theta, np.zeros_like(theta)], axis=1)

    def _draw(self, surface, x, goal, history):
        p = self.system.parameters
        slider = float(self._slider(x[0])[0])
        rendering.draw_crank(surface, x[0], slider, goal[0], p["R"], p["l"], p["h"], p["s"])


def wrap_array(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


class CrankSliderVectorEnv(LagrangianVectorEnv):
    """`CrankSliderEnv` copies stepped in one batched call (see `LagrangianVectorEnv`)."""

    env_class = CrankSliderEnv
