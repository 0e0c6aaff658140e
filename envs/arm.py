"""Lagrange/TwoLinkArm-v0: drive the fully actuated two-link arm to a goal configuration."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import rendering
from .base import ANGLE_LIMIT, LagrangianEnv, LagrangianVectorEnv, wrap

RATE_LIMIT = 8 * np.pi
"""Bound on |theta1'|, |theta2'| (rad/s): observation bound; beyond it the episode diverged."""

ANGLE_TOLERANCE = 0.1
"""Success: both wrapped angle errors below this (rad) ..."""
RATE_TOLERANCE = 0.5
"""... and both rates below this (rad/s)."""


@njit(cache=True)
def evaluate(X, A, G, Y, c, obs, terms, flags):
    """Observation, reward terms (angle, precision, rate, effort), [terminated, success] per row."""
    for b in range(X.shape[0]):
        th1, th2, w1, w2 = X[b, 0], X[b, 1], X[b, 2], X[b, 3]
        obs[b, 0] = math.cos(th1)
        obs[b, 1] = math.cos(th2)
        obs[b, 2] = math.sin(th1)
        obs[b, 3] = math.sin(th2)
        obs[b, 4] = w1
        obs[b, 5] = w2
        obs[b, 6] = math.cos(G[b, 0])
        obs[b, 7] = math.cos(G[b, 1])
        obs[b, 8] = math.sin(G[b, 0])
        obs[b, 9] = math.sin(G[b, 1])
        e1, e2 = wrap(th1 - G[b, 0]), wrap(th2 - G[b, 1])
        obs[b, 10] = math.cos(e1)
        obs[b, 11] = math.cos(e2)
        obs[b, 12] = math.sin(e1)
        obs[b, 13] = math.sin(e2)
        terms[b, 0] = -(e1 * e1 + e2 * e2)
        terms[b, 1] = -math.sqrt(e1 * e1 + e2 * e2)
        terms[b, 2] = -0.01 * (w1 * w1 + w2 * w2)
        terms[b, 3] = -0.001 * (A[b, 0] * A[b, 0] + A[b, 1] * A[b, 1])
        flags[b, 0] = False
        flags[b, 1] = (
            abs(e1) < ANGLE_TOLERANCE
            and abs(e2) < ANGLE_TOLERANCE
            and abs(w1) < RATE_TOLERANCE
            and abs(w2) < RATE_TOLERANCE
        )


class TwoLinkArmEnv(LagrangianEnv):
    """
    ## Description
    The planar two-link arm of section 7.4 (model `two_link_arm`) hangs from a fixed
    shoulder A under gravity, with a motor at the shoulder (ground on link 1) and one at the
    elbow C (link 1 on link 2). The task: bring the arm to a goal configuration drawn at
    reset anywhere on the torus of configurations, inverted ones included, and hold it.

    ```
            A (shoulder)          theta1, theta2: absolute angles of the links from
            |\\                    the downward vertical, counter-clockwise positive
            | \\ theta1            (0 hangs, pi is inverted).
            |  C (elbow)
            |  |\\ theta2
               |  D (tip)
    ```

    ## Action Space
    | Num | Action                        | Min | Max | Unit                    |
    |-----|-------------------------------|-----|-----|-------------------------|
    | 0   | shoulder motor M1             | -1  | 1   | x `max_torque[0]` N*m   |
    | 1   | elbow motor M2                | -1  | 1   | x `max_torque[1]` N*m   |

    Actions outside [-1, 1] are clipped; NaN or inf raise ValueError. The default limits
    are 1.5 times the largest static holding torques, (m1 l1 + m2 l) g + m2 l2 g and
    m2 l2 g: 29.4 and 7.4 N*m for the default arm, so any configuration can be held.

    ## Observation Space
    float32, shape (14,):
    | Num   | Observation                             | Min   | Max  |
    |-------|-----------------------------------------|-------|------|
    | 0-1   | cos theta1, cos theta2                  | -1    | 1    |
    | 2-3   | sin theta1, sin theta2                  | -1    | 1    |
    | 4-5   | theta1', theta2' (rad/s)                | -8 pi | 8 pi |
    | 6-7   | cos of the goal angles theta1*, theta2* | -1    | 1    |
    | 8-9   | sin of the goal angles theta1*, theta2* | -1    | 1    |
    | 10-11 | cos of the goal errors e1, e2           | -1    | 1    |
    | 12-13 | sin of the goal errors e1, e2           | -1    | 1    |

    e = theta - theta*, wrapped to [-pi, pi). Columns 10-13 are functions of columns 0-3 and
    6-9, given so that the policy need not learn angle differences through products of
    cosines and sines.

    ## Rewards
    Computed on the state after the step, the sum of four terms (in `info["reward_terms"]`):
    `angle` = -(e1^2 + e2^2) with e the goal error wrapped to [-pi, pi); `precision` =
    -sqrt(e1^2 + e2^2), whose slope does not vanish at the goal as the quadratic's does,
    so the last tenths of a radian still pay; `rate` = -0.01 (theta1'^2 + theta2'^2);
    `effort` = -0.001 |action|^2.

    ## Starting State
    Angles uniform in [-pi, pi), rates uniform in [-0.1, 0.1] rad/s, the goal angles
    uniform in [-pi, pi). `reset(options={"state": x, "goal": (theta1, theta2)})` sets them.

    ## Episode End
    No termination. Truncation: 200 steps (10 s), or divergence (a non-finite state or a
    rate beyond 8 pi rad/s; then `info["diverged"]` is True). `info["is_success"]`: both
    wrapped angle errors below 0.1 rad and both rates below 0.5 rad/s; the task succeeds
    if that holds at the end of the episode.

    ## Arguments
    `gymnasium.make("Lagrange/TwoLinkArm-v0", control_period=0.05, substeps=25,
    max_torque=None, render_mode=None, **model_parameters)` with the parameters of
    `two_link_arm` by name (m1, m2, l, l1, l2, Ibar1, Ibar2, g). Integration: RK4, 25
    substeps of 2 ms per 50 ms step; an unforced episode from the starting distribution
    keeps the energy within 1e-6 of the potential-energy range, inverted minus hanging
    (3e-7 measured over 100 episodes, tests/envs/test_physics.py; 20 substeps gave 9e-7).

    ## Version History
    * v0: initial version.
    """

    model = "two_link_arm"
    actuated = (0, 1)
    default_control_period = 0.05
    default_substeps = 25
    goal_size = 2
    reward_names = ("angle", "precision", "rate", "effort")
    evaluate = staticmethod(evaluate)

    def _periodic(self):
        return (True, True)

    def _default_max_torque(self) -> np.ndarray:
        p = self.system.parameters
        shoulder = (p["m1"] * p["l1"] + p["m2"] * p["l"]) * p["g"] + p["m2"] * p["l2"] * p["g"]
        return 1.5 * np.array([shoulder, p["m2"] * p["l2"] * p["g"]])

    def _observation_high(self) -> np.ndarray:
        high = np.ones(14)
        high[4:6] = RATE_LIMIT
        return high

    def _state_limits(self) -> np.ndarray:
        return np.array([ANGLE_LIMIT, ANGLE_LIMIT, RATE_LIMIT, RATE_LIMIT])

    def _sample_start(self, rng):
        x = np.concatenate([rng.uniform(-np.pi, np.pi, 2), rng.uniform(-0.1, 0.1, 2)])
        return x, rng.uniform(-np.pi, np.pi, 2)

    def _state_from_observation(self, obs):
        q = np.arctan2(obs[:, 2:4], obs[:, 0:2])
        return np.concatenate([q, obs[:, 4:6]], axis=1)

    def _goal_from_observation(self, obs):
        return np.arctan2(obs[:, 8:10], obs[:, 6:8])

    def _operating_state(self, goal, x):
        return np.concatenate([goal, np.zeros_like(goal)], axis=1)

    def _draw(self, surface, x, goal, history):
        p = self.system.parameters
        rendering.draw_arm(surface, x, goal, p["l"], 2 * p["l2"])


class TwoLinkArmVectorEnv(LagrangianVectorEnv):
    """`TwoLinkArmEnv` copies stepped in one batched call (see `LagrangianVectorEnv`)."""

    env_class = TwoLinkArmEnv
