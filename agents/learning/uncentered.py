"""Observation statistics about zero: how a training run's VecNormalize scales observations
unless its `normalize` table says `center: true`.

SB3's VecNormalize subtracts each observation's running mean. An MLP policy as SB3 builds it
(zero biases, odd activations) starts as an odd function of its input, so its action is zero
where the normalised observation is zero, which is at the running mean: the mean of what the
first, poor episodes visited. Where an observation's goal is zero (a rate to be stopped, an
error) and the system keeps that state without input (a yaw rate that rolling without slip
holds), the policy settles at that mean, and the rollouts then keep the mean there. Scaled
about zero instead (divided by the running root mean square), the zero the policy starts
from is the observation's own zero.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.vec_env import VecNormalize


class UncenteredMeanStd(RunningMeanStd):
    """SB3's running statistics with the mean held at zero and `var` the running mean of the
    squares, so VecNormalize's (obs - mean) / sqrt(var + eps) divides by the root mean
    square. Pickled with the run's vecnormalize.pkl; read back by any code that reads
    `mean` and `var`."""

    def copy(self) -> UncenteredMeanStd:
        out = UncenteredMeanStd(shape=self.mean.shape)
        out.var, out.count = self.var.copy(), float(self.count)
        return out

    def update_from_moments(self, batch_mean, batch_var, batch_count: float) -> None:
        total = self.count + batch_count
        second = np.asarray(batch_var) + np.square(batch_mean)
        self.var = self.var + (second - self.var) * (batch_count / total)
        self.count = total


def uncentered(venv: VecNormalize) -> VecNormalize:
    """`venv` with its observation statistics about zero (before it has seen any)."""
    rms = venv.obs_rms
    if isinstance(rms, dict):
        venv.obs_rms = {k: UncenteredMeanStd(shape=v.mean.shape) for k, v in rms.items()}
    else:
        venv.obs_rms = UncenteredMeanStd(shape=rms.mean.shape)
    return venv
