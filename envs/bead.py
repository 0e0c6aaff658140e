"""Lagrange/BeadOnRod-v0: hold a bead at a target distance on a motor-driven rod."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import rendering
from .base import ANGLE_LIMIT, LagrangianEnv, LagrangianVectorEnv, wrap

SPEED_LIMIT = 20.0
"""Bound on |r'| (m/s): observation bound; beyond it the episode diverged."""
RATE_LIMIT = 8 * np.pi
"""Bound on |phi'| (rad/s)."""
TARGET_RANGE = 0.8
"""Targets are drawn within this fraction of the half-length of the rod."""
DISTANCE_TOLERANCE = 0.05
"""Success: |r - r*| below this fraction of the half-length ..."""
SPEED_TOLERANCE = 0.05
"""... and |r'| below this (m/s)."""


@njit(cache=True)
def evaluate(X, A, G, Y, c, obs, terms, flags):
    """Observation, reward terms (alive, distance, angle, effort), [terminated, success].
    c = [half-length of the rod]."""
    half = c[0]
    for b in range(X.shape[0]):
        r, phi, rd, phid = X[b, 0], X[b, 1], X[b, 2], X[b, 3]
        obs[b, 0] = r
        obs[b, 1] = math.cos(phi)
        obs[b, 2] = math.sin(phi)
        obs[b, 3] = rd
        obs[b, 4] = phid
        obs[b, 5] = G[b, 0]
        e = (r - G[b, 0]) / half
        a = wrap(phi)
        terms[b, 0] = 1.0
        terms[b, 1] = -e * e
        terms[b, 2] = -0.1 * a * a
        terms[b, 3] = -0.001 * A[b, 0] * A[b, 0]
        flags[b, 0] = abs(r) > half
        flags[b, 1] = abs(e) < DISTANCE_TOLERANCE and abs(rd) < SPEED_TOLERANCE


class BeadOnRodEnv(LagrangianEnv):
    """
    ## Description
    The bead of problem 7/4 on a rod that now turns freely about its pivot O (at the rod's
    middle) in a vertical plane, driven by a motor (model `bead_on_driven_rod`). The task:
    bring the bead to a target distance r* from O and hold it there, without letting it
    slide off either end.

    ```
                         bead (r > 0)
                     ___o____               phi: the rod's angle above the horizontal,
            ________/  O  phi               counter-clockwise positive;
                     (pivot, motor)         r: the bead's signed distance from O along
                                            the rod, positive towards the end at phi.
    ```

    ## Action Space
    | Num | Action            | Min | Max | Unit                    |
    |-----|-------------------|-----|-----|-------------------------|
    | 0   | torque on the rod | -1  | 1   | x `max_torque` (2 N*m)  |

    Clipped to [-1, 1]; NaN or inf raise ValueError. Holding the bead at rest at r needs
    m g r (0.98 N*m at the end of the default rod).

    ## Observation Space
    float32, shape (6,): r (m, in [-rod_length, rod_length]), cos phi, sin phi, r' (m/s,
    in [-20, 20]), phi' (rad/s, in [-8 pi, 8 pi]), the target r* (m).

    ## Rewards
    On the state after the step, the sum of `alive` = 1, `distance` = -((r - r*) /
    (rod_length / 2))^2, `angle` = -0.1 phi^2 (phi wrapped to [-pi, pi)) and `effort` =
    -0.001 action^2. The alive bonus makes leaving the rod early a loss.

    ## Starting State
    r uniform within +-0.5 of the half-length, phi uniform in [-0.1, 0.1] rad, rates 0;
    the target r* uniform within +-0.8 of the half-length. `reset(options={"state": x,
    "goal": (r*,)})` sets them.

    ## Episode End
    Termination: the bead leaves the rod, |r| > rod_length / 2. Truncation: 200 steps
    (10 s), or divergence (non-finite state, |r| > rod_length or a rate beyond its bound;
    `info["diverged"]`). `info["is_success"]`: |r - r*| < 0.05 rod_length / 2 and |r'| <
    0.05 m/s.

    ## Arguments
    `gymnasium.make("Lagrange/BeadOnRod-v0", control_period=0.05, substeps=5,
    max_torque=2.0, render_mode=None, **model_parameters)` with the parameters of
    `bead_on_driven_rod` by name (m, J, rod_length, g). Integration: RK4, 5 substeps of
    10 ms per 50 ms step; an unforced episode keeps the energy within 1e-8 of m g
    rod_length / 2 (5e-9 measured over 100 episodes, tests/envs/test_physics.py).

    ## Version History
    * v0: initial version.
    """

    model = "bead_on_driven_rod"
    actuated = (0,)
    default_control_period = 0.05
    default_substeps = 5
    default_max_torque = (2.0,)
    goal_size = 1
    reward_names = ("alive", "distance", "angle", "effort")
    evaluate = staticmethod(evaluate)

    @property
    def _half(self) -> float:
        return self.system.parameters["rod_length"] / 2

    def _periodic(self):
        return (False, True)

    def _task_constants(self) -> np.ndarray:
        return np.array([self._half])

    def _observation_high(self) -> np.ndarray:
        L = 2 * self._half
        return np.array([L, 1, 1, SPEED_LIMIT, RATE_LIMIT, L])

    def _state_limits(self) -> np.ndarray:
        return np.array([2 * self._half, ANGLE_LIMIT, SPEED_LIMIT, RATE_LIMIT])

    def _sample_start(self, rng):
        h = self._half
        x = np.array([rng.uniform(-0.5 * h, 0.5 * h), rng.uniform(-0.1, 0.1), 0.0, 0.0])
        return x, np.array([rng.uniform(-TARGET_RANGE * h, TARGET_RANGE * h)])

    def _check_goal(self, goal):
        if abs(goal[0]) >= self._half:
            raise ValueError(f"Target r* must lie on the rod, |r*| < {self._half}; got {goal[0]}.")

    def _state_from_observation(self, obs):
        phi = np.arctan2(obs[:, 2], obs[:, 1])
        return np.stack([obs[:, 0], phi, obs[:, 3], obs[:, 4]], axis=1)

    def _goal_from_observation(self, obs):
        return obs[:, 5:6].copy()

    def _operating_state(self, goal, x):
        """The bead at rest at r* on the rod held horizontal (the only equilibria)."""
        z = np.zeros_like(goal)
        return np.concatenate([goal, z, z, z], axis=1)

    def _draw(self, surface, x, goal, history):
        rendering.draw_bead(surface, x[0], x[1], goal[0], 2 * self._half)


class BeadOnRodVectorEnv(LagrangianVectorEnv):
    """`BeadOnRodEnv` copies stepped in one batched call (see `LagrangianVectorEnv`)."""

    env_class = BeadOnRodEnv
