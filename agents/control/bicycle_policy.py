"""The speed-scheduled LQR that rides `Lagrange/Bicycle-v0` (the task's heuristic baseline).

Plain LQR (`agents.control.lqr_policy`) refuses the bicycle: its constraints tie the pitch and the
yaw rate to lean and steer, so the full linearisation has no exact cut to the observed
states. This designs on the constraint-reduced linearisation instead
(`dynamics.bicycle.reduced_linearization`), scheduled on the commanded speed.
"""

from __future__ import annotations

import numpy as np

from dynamics.bicycle import reduced_linearization

from ..common import lagrange_env
from .linear import discretize
from .lqr_policy import bryson_weights, dlqr
from .policies import Policy, _single_action_space


class BicycleLQRPolicy(Policy):
    """Speed-scheduled LQR for `Lagrange/Bicycle-v0`: steer torque from a discrete LQR on
    (phi, delta, phi', delta'), designed on the constraint-reduced linearisation
    (`dynamics.bicycle.reduced_linearization`) at the commanded speed v* of each
    observation (gains cached per 0.01 m/s), weighted by the task's `LQRHints` (Bryson's
    scales, R); the drive torque T_R = speed_gain (v - v*) (N*m per m/s; positive T_R
    brakes) holds the speed."""

    STATES = ("phi", "delta", "phi_dot", "delta_dot")

    def __init__(self, env, speed_gain: float = 30.0):
        self.env = lagrange_env(env)
        super().__init__(_single_action_space(self.env))
        task, self.system = self.env.task, self.env.system
        if tuple(task.actuated) != ("T_delta", "T_R"):
            raise ValueError(f"BicycleLQRPolicy drives (T_delta, T_R), not {task.actuated}.")
        self.columns = _observation_columns(task, self.STATES + ("v - v*", "v*"))
        self.Q = np.diag(bryson_weights(task.lqr, self.STATES))
        self.R = np.atleast_2d(np.broadcast_to(task.lqr.R, (2,))[0])
        self.max_input = self.env.plant.max_input
        self.speed_gain = float(speed_gain)
        self._gains: dict[float, np.ndarray] = {}

    def gain(self, v_star: float) -> np.ndarray:
        """K (1 x 4) in action units at commanded speed v_star (rounded to 0.01 m/s)."""
        v = round(float(v_star), 2)
        K = self._gains.get(v)
        if K is None:
            A4, B2 = reduced_linearization(self.system, v)
            B = np.zeros((4, 1))
            B[2:, 0] = B2[:, 1] * self.max_input[0]  # the steer torque, in action units
            Ad, Bd = discretize(A4, B, float(self.env.control_period))
            K = dlqr(Ad, Bd, self.Q, self.R)[0]
            self._gains[v] = K
        return K

    def act(self, obs):
        s = obs[:, self.columns[:4]]
        error, v_star = obs[:, self.columns[4]], obs[:, self.columns[5]]
        a = np.empty((len(obs), 2))
        for i in range(len(obs)):
            a[i, 0] = -(self.gain(v_star[i]) @ s[i])[0]
        a[:, 1] = self.speed_gain * error / self.max_input[1]
        return a


def _observation_columns(task, names) -> list[int]:
    """The observation columns of the one-column (`Value`, `Derived`) features `names`."""
    from envs.task import Derived, Value

    width = {"Angle": 2, "AngleError": 2}
    where, col = {}, 0
    for f in task.observation:
        if isinstance(f, (Value, Derived)):
            where[f.name] = col
        col += width.get(type(f).__name__, 1)
    missing = [k for k in names if k not in where]
    if missing:
        raise ValueError(f"Task {task.name!r} does not observe {missing} in one column each.")
    return [where[k] for k in names]
