"""Lagrange/RollingDisk-v0: roll a thin disk at a commanded speed and heading without falling."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import rendering
from .base import ANGLE_LIMIT, LagrangianEnv, LagrangianVectorEnv, wrap

LEAN_LIMIT = np.pi / 6
"""The episode terminates when |theta - pi/2| (the lean from upright) exceeds this (rad)."""
SPEED_RANGE = (0.5, 3.0)
"""Commanded speeds are drawn uniformly from this range (m/s)."""
TILT_RATE_LIMIT = 8 * np.pi
"""Bound on |theta'| and |phi'| (rad/s)."""
SPIN_RATE_LIMIT = 40 * np.pi
"""Bound on |psi'| (rad/s)."""
SPEED_LIMIT = 20.0
"""Bound on |x'|, |z'| (m/s)."""
SPEED_TOLERANCE = 0.1
"""Success: |v - v*| below this (m/s) ..."""
HEADING_TOLERANCE = 0.1
"""... and the heading within this (rad) of the command, upright."""


@njit(cache=True)
def evaluate(X, A, G, Y, c, obs, terms, flags):
    """Observation, reward terms (alive, speed, heading, lean, effort), [terminated,
    success] per row. c = [radius]."""
    radius = c[0]
    for b in range(X.shape[0]):
        theta, phi = X[b, 2], X[b, 3]
        thetad, phid, psid = X[b, 7], X[b, 8], X[b, 9]
        obs[b, 0] = math.cos(theta)
        obs[b, 1] = math.sin(theta)
        obs[b, 2] = math.cos(phi)
        obs[b, 3] = math.sin(phi)
        obs[b, 4] = thetad
        obs[b, 5] = phid
        obs[b, 6] = psid
        obs[b, 7] = G[b, 0]
        obs[b, 8] = math.cos(G[b, 1])
        obs[b, 9] = math.sin(G[b, 1])
        speed_error = -radius * psid - G[b, 0]
        heading_error = wrap(phi - G[b, 1])
        lean = theta - 0.5 * math.pi
        terms[b, 0] = 1.0
        terms[b, 1] = -speed_error * speed_error
        terms[b, 2] = -heading_error * heading_error
        terms[b, 3] = -lean * lean
        terms[b, 4] = -0.001 * (A[b, 0] * A[b, 0] + A[b, 1] * A[b, 1])
        flags[b, 0] = abs(lean) > LEAN_LIMIT
        flags[b, 1] = (
            abs(speed_error) < SPEED_TOLERANCE
            and abs(heading_error) < HEADING_TOLERANCE
            and abs(lean) <= LEAN_LIMIT
        )


class RollingDiskEnv(LagrangianEnv):
    """
    ## Description
    The thin uniform disk of section 7.5 (model `rolling_disk`) rolls without slipping on
    the horizontal floor. A drive torque acts about its axle and a steering torque about
    the vertical. The task: roll at a commanded speed v* and heading phi*, drawn at reset,
    without falling over.

    ```
          y (up)                 theta: tilt of the disk's plane from the floor, pi/2
          |    . disk            upright (the lean is theta - pi/2);
          |  /  \\  i'            phi: heading, the rolling direction is
          | |  G | --->           i' = (sin phi, 0, cos phi) in the floor's (x, z);
          |  \\  /                psi: spin about the axle; forward speed v = -r psi'.
          |___o______ x          (x, z): the contact point; x' = v sin phi,
         /  contact               z' = v cos phi (the rolling constraints).
        z
    ```
    Upright straight rolling of this disk is self-stable when the spin exceeds
    sqrt(g / (3 r)) (v > 0.99 m/s for the default r = 0.3 m); slower, it must be
    balanced by steering.

    ## Action Space
    | Num | Action                     | Min | Max | Unit                       |
    |-----|----------------------------|-----|-----|----------------------------|
    | 0   | drive torque about the axle| -1  | 1   | x `max_torque[0]` (0.5 N*m)|
    | 1   | steering torque, vertical  | -1  | 1   | x `max_torque[1]` (0.1 N*m)|

    Clipped to [-1, 1]; NaN or inf raise ValueError. A positive drive torque spins psi
    up, i.e. brakes forward rolling (v = -r psi').

    ## Observation Space
    float32, shape (10,): cos theta, sin theta, cos phi, sin phi (each in [-1, 1]), theta',
    phi' (rad/s, in [-8 pi, 8 pi]), psi' (rad/s, in [-40 pi, 40 pi]), the commanded speed
    v* (m/s), cos phi*, sin phi*. The cyclic coordinates x, z, psi are not observed
    (`state_from_observation` returns them as 0, with x', z' from the constraints).

    ## Rewards
    On the state after the step, the sum of `alive` = 1, `speed` = -(v - v*)^2,
    `heading` = -(phi - phi*)^2 (wrapped to [-pi, pi)), `lean` = -(theta - pi/2)^2 and
    `effort` = -0.001 |action|^2. The alive bonus makes falling a loss.

    ## Starting State
    v* uniform in [0.5, 3] m/s and phi* uniform in [-pi, pi); the disk rolls at v* with
    heading phi* + U(-pi/4, pi/4), lean U(-0.05, 0.05) rad, theta', phi' U(-0.1, 0.1)
    rad/s, at the origin. `reset(options={"state": x, "goal": (v*, phi*)})` sets them
    (a given state's rates are projected onto the rolling constraints).

    ## Episode End
    Termination: the lean |theta - pi/2| exceeds pi/6. Truncation: 400 steps (20 s), or
    divergence (non-finite state or a rate beyond its bound; `info["diverged"]`).
    `info["is_success"]`: |v - v*| < 0.1 m/s and heading within 0.1 rad, not fallen.
    `info["constraint_residual"]`: the rolling constraints' residual (m/s), at round-off:
    each RK4 substep is projected back onto them.

    ## Arguments
    `gymnasium.make("Lagrange/RollingDisk-v0", control_period=0.05, substeps=10,
    max_torque=(0.5, 0.1), render_mode=None, **model_parameters)` with the parameters of
    `rolling_disk` by name (m, r, I, J, g). Integration: RK4, 10 substeps of 5 ms per 50 ms
    step; an unforced episode keeps the energy within 1e-8 of its initial value (relative;
    2e-9 measured over 100 episodes, tests/envs/test_physics.py).

    ## Version History
    * v0: initial version.
    """

    model = "rolling_disk"
    actuated = (0, 1)
    default_control_period = 0.05
    default_substeps = 10
    default_max_torque = (0.5, 0.1)
    goal_size = 2
    reward_names = ("alive", "speed", "heading", "lean", "effort")
    evaluate = staticmethod(evaluate)

    @property
    def _radius(self) -> float:
        return self.system.parameters["r"]

    def _periodic(self):
        return (False, False, True, True, True)

    def _task_constants(self) -> np.ndarray:
        return np.array([self._radius])

    def _observation_high(self) -> np.ndarray:
        vmax = SPEED_RANGE[1]
        t, s = TILT_RATE_LIMIT, SPIN_RATE_LIMIT
        return np.array([1, 1, 1, 1, t, t, s, vmax, 1, 1], dtype=np.float64)

    def _state_limits(self) -> np.ndarray:
        a, t, v = ANGLE_LIMIT, TILT_RATE_LIMIT, SPEED_LIMIT
        return np.array([a, a, a, a, a, v, v, t, t, SPIN_RATE_LIMIT])

    def _sample_start(self, rng):
        speed = rng.uniform(*SPEED_RANGE)
        heading = rng.uniform(-np.pi, np.pi)
        phi = heading + rng.uniform(-np.pi / 4, np.pi / 4)
        theta = np.pi / 2 + rng.uniform(-0.05, 0.05)
        thetad, phid = rng.uniform(-0.1, 0.1, 2)
        x = self._rolling_state(theta, phi, thetad, phid, speed)
        return x, np.array([speed, heading])

    def _rolling_state(self, theta, phi, thetad, phid, speed):
        """State at the origin rolling at `speed` with the given angles and rates."""
        psid = -speed / self._radius
        return np.array(
            [0, 0, theta, phi, 0, speed * np.sin(phi), speed * np.cos(phi), thetad, phid, psid],
            dtype=np.float64,
        )

    def _check_goal(self, goal):
        lo, hi = SPEED_RANGE
        if not lo <= goal[0] <= hi:
            raise ValueError(f"Commanded speed must lie in [{lo}, {hi}] m/s; got {goal[0]}.")

    def _state_from_observation(self, obs):
        theta = np.arctan2(obs[:, 1], obs[:, 0])
        phi = np.arctan2(obs[:, 3], obs[:, 2])
        v = -self._radius * obs[:, 6]
        z = np.zeros_like(theta)
        cols = [
            z,
            z,
            theta,
            phi,
            z,
            v * np.sin(phi),
            v * np.cos(phi),
            obs[:, 4],
            obs[:, 5],
            obs[:, 6],
        ]
        return np.stack(cols, axis=1)

    def _goal_from_observation(self, obs):
        return np.stack([obs[:, 7], np.arctan2(obs[:, 9], obs[:, 8])], axis=1)

    def _operating_state(self, goal, x):
        """Upright straight rolling at v* along phi*: a steady motion (theta = pi/2,
        phi' = 0, psi' = -v*/r, cyclic coordinates 0)."""
        speed, heading = goal[:, 0], goal[:, 1]
        z = np.zeros_like(speed)
        cols = [z, z, z + np.pi / 2, heading, z, speed * np.sin(heading), speed * np.cos(heading)]
        return np.stack(cols + [z, z, -speed / self._radius], axis=1)

    def _operating_input(self, x0):
        """Upright straight rolling needs no torque."""
        return np.zeros(x0.shape[:-1] + (self.system.n_u,))

    def _draw(self, surface, x, goal, history):
        track = None if history is None else [(h[0], h[1]) for h in history]
        rendering.draw_disk(surface, x, goal, self._radius, track)


class RollingDiskVectorEnv(LagrangianVectorEnv):
    """`RollingDiskEnv` copies stepped in one batched call (see `LagrangianVectorEnv`)."""

    env_class = RollingDiskEnv
