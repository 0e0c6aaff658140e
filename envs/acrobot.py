"""Lagrange/Acrobot-v0: swing the two-link arm up with its elbow motor alone and balance it."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import rendering
from .base import ANGLE_LIMIT, LagrangianEnv, LagrangianVectorEnv, wrap

RATE_LIMIT = 8 * np.pi
"""Bound on |theta1'|, |theta2'| (rad/s): observation bound; beyond it the episode diverged."""
ANGLE_TOLERANCE = 0.2
"""Success: both links within this (rad) of inverted ..."""
RATE_TOLERANCE = 1.0
"""... and both rates below this (rad/s)."""


@njit(cache=True)
def evaluate(X, A, G, Y, c, obs, terms, flags):
    """Observation, reward terms (height, rate, effort), [terminated, success] per row.
    c = [l, length of link 2]."""
    l, l2 = c[0], c[1]
    for b in range(X.shape[0]):
        th1, th2, w1, w2 = X[b, 0], X[b, 1], X[b, 2], X[b, 3]
        c1, c2 = math.cos(th1), math.cos(th2)
        obs[b, 0] = c1
        obs[b, 1] = c2
        obs[b, 2] = math.sin(th1)
        obs[b, 3] = math.sin(th2)
        obs[b, 4] = w1
        obs[b, 5] = w2
        terms[b, 0] = -(l * c1 + l2 * c2) / (l + l2)  # tip height / reach, in [-1, 1]
        terms[b, 1] = -0.01 * (w1 * w1 + w2 * w2)
        terms[b, 2] = -0.001 * A[b, 0] * A[b, 0]
        flags[b, 0] = False
        flags[b, 1] = (
            abs(wrap(th1 - G[b, 0])) < ANGLE_TOLERANCE
            and abs(wrap(th2 - G[b, 1])) < ANGLE_TOLERANCE
            and abs(w1) < RATE_TOLERANCE
            and abs(w2) < RATE_TOLERANCE
        )


class AcrobotEnv(LagrangianEnv):
    """
    ## Description
    The two-link arm of section 7.4 (model `two_link_arm`, defaults: two uniform 1 kg, 1 m
    rods) with the shoulder motor removed: only the elbow motor M2 (link 1 on link 2)
    acts. Its torque is too small to hold link 2 horizontal (m2 l2 g = 4.9 N*m for the
    default arm), so the arm must be swung up by pumping energy, then balanced inverted.

    ```
            A (shoulder, free)    theta1, theta2: absolute angles of the links from
            |\\                    the downward vertical, counter-clockwise positive
            | \\ theta1            (0 hangs; the goal is theta1 = theta2 = pi).
            |  C (elbow motor)
            |  |\\ theta2
               |  D (tip)
    ```

    ## Action Space
    | Num | Action          | Min | Max | Unit                   |
    |-----|-----------------|-----|-----|------------------------|
    | 0   | elbow motor M2  | -1  | 1   | x `max_torque` (3 N*m) |

    Actions outside [-1, 1] are clipped; NaN or inf raise ValueError. The model's input is
    [M1, M2] = [0, action * max_torque].

    ## Observation Space
    float32, shape (6,): cos theta1, cos theta2, sin theta1, sin theta2 (each in [-1, 1]),
    theta1', theta2' (rad/s, in [-8 pi, 8 pi]). The goal (inverted) is fixed, so it is
    not observed; `goal_from_observation` returns (pi, pi).

    ## Rewards
    On the state after the step, the sum of `height` = -(l cos theta1 + 2 l2 cos theta2) /
    (l + 2 l2), the tip's height over its reach (from -1 hanging to 1 inverted), `rate` =
    -0.01 (theta1'^2 + theta2'^2) and `effort` = -0.001 action^2.

    ## Starting State
    Hanging: angles and rates uniform in [-0.1, 0.1] (rad, rad/s).
    `reset(options={"state": x})` sets the state.

    ## Episode End
    No termination. Truncation: 500 steps (25 s), or divergence (a non-finite state or a
    rate beyond 8 pi rad/s; `info["diverged"]`). `info["is_success"]`: both links within
    0.2 rad of inverted and both rates below 1 rad/s.

    ## Arguments
    `gymnasium.make("Lagrange/Acrobot-v0", control_period=0.05, substeps=25,
    max_torque=3.0, render_mode=None, **model_parameters)` with the parameters of
    `two_link_arm` by name. Integration: RK4, 25 substeps of 2 ms per 50 ms step; an
    unforced episode from the starting distribution keeps the energy within 1e-9 of the
    potential-energy range (3e-12 measured over 100 episodes, tests/envs/test_physics.py;
    swinging up, the arm moves as fast as TwoLinkArm's, which keeps 1e-6 at this step).

    ## Version History
    * v0: initial version.
    """

    model = "two_link_arm"
    actuated = (1,)
    default_control_period = 0.05
    default_substeps = 25
    default_max_torque = (3.0,)
    goal_size = 2
    reward_names = ("height", "rate", "effort")
    evaluate = staticmethod(evaluate)

    def _periodic(self):
        return (True, True)

    def _task_constants(self) -> np.ndarray:
        p = self.system.parameters
        return np.array([p["l"], 2 * p["l2"]])

    def _observation_high(self) -> np.ndarray:
        return np.array([1, 1, 1, 1, RATE_LIMIT, RATE_LIMIT], dtype=np.float64)

    def _state_limits(self) -> np.ndarray:
        return np.array([ANGLE_LIMIT, ANGLE_LIMIT, RATE_LIMIT, RATE_LIMIT])

    def _sample_start(self, rng):
        return rng.uniform(-0.1, 0.1, 4), np.array([np.pi, np.pi])

    def _check_goal(self, goal):
        if not np.allclose(np.cos(goal), -1.0):
            raise ValueError(f"The acrobot's goal is inverted, (pi, pi); got {goal}.")

    def _state_from_observation(self, obs):
        return np.concatenate([np.arctan2(obs[:, 2:4], obs[:, 0:2]), obs[:, 4:6]], axis=1)

    def _goal_from_observation(self, obs):
        return np.full((len(obs), 2), np.pi)

    def _operating_state(self, goal, x):
        return np.concatenate([goal, np.zeros_like(goal)], axis=1)

    def _draw(self, surface, x, goal, history):
        p = self.system.parameters
        rendering.draw_arm(surface, x, goal, p["l"], 2 * p["l2"])


class AcrobotVectorEnv(LagrangianVectorEnv):
    """`AcrobotEnv` copies stepped in one batched call (see `LagrangianVectorEnv`)."""

    env_class = AcrobotEnv
