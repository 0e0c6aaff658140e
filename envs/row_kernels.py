"""The runtime's own compiled kernels, over the rows of its arrays: the actions into
inputs (`apply_actions`), the step's bookkeeping and divergence (`advance`), and the
results (`finish`: reward terms clipped and summed, termination, the early-end penalty,
the observation handed out). `envs.observation.observe` writes the observation."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def apply_actions(actions, input_mid, input_half, actuated, clipped, U) -> bool:
    """Clip actions to [-1, 1] into `clipped` and map them into the actuated columns of
    the input rows U (input = mid + action * half: action -1 and 1 are the input's
    limits); False (and nothing written) if any action is NaN or inf."""
    for b in range(actions.shape[0]):
        for j in range(actions.shape[1]):
            if not np.isfinite(actions[b, j]):
                return False
    for b in range(actions.shape[0]):
        for j in range(actions.shape[1]):
            a = min(max(actions[b, j], -1.0), 1.0)
            clipped[b, j] = a
            U[b, actuated[j]] = input_mid[j] + a * input_half[j]
    return True


@njit(cache=True)
def advance(X, X_next, limits, diverged, T, dt, steps, horizon, steps_left) -> bool:
    """After a step into X_next: time and step counts, the steps left to `horizon` (none
    when it is negative: no time limit), X = X_next row by row except where X_next is not
    finite (that row keeps its previous, finite, state), and diverged[b] = some
    |X_next[b, i]| > limits[i] or non-finite. Whether any row diverged."""
    any_bad = False
    for b in range(X.shape[0]):
        T[b] += dt
        steps[b] += 1
        steps_left[b] = max(horizon - steps[b], 0) if horizon >= 0 else 0.0
        bad = False
        finite = True
        for i in range(X.shape[1]):
            v = X_next[b, i]
            if not np.isfinite(v):
                finite = False
                bad = True
            elif abs(v) > limits[i]:
                bad = True
        if finite:
            for i in range(X.shape[1]):
                X[b, i] = X_next[b, i]
        diverged[b] = bad
        any_bad |= bad
    return any_bad


@njit(cache=True)
def finish(
    terms,
    low,
    high,
    failed,
    diverged,
    steps_left,
    lowest,
    rewards,
    terminated,
    success,
    obs,
    obs_low,
    obs32,
) -> bool:
    """Clip each reward term into its bounds and sum them; a row terminates when it failed
    or diverged, and then adds the early-end penalty steps_left * min(0, lowest) and is no
    success; the observation is handed out as float32. A NaN or inf reward term or
    observation (a task function's) counts as divergence: the value becomes its lower
    bound, so nothing non-finite reaches the agent. Whether that happened to some row."""
    penalty = min(0.0, lowest)
    any_bad = False
    for b in range(terms.shape[0]):
        r = 0.0
        bad = False
        for k in range(terms.shape[1]):
            v = terms[b, k]
            if not np.isfinite(v):
                bad = True
                v = low[k]
            v = min(max(v, low[k]), high[k])
            terms[b, k] = v
            r += v
        for j in range(obs.shape[1]):
            if not np.isfinite(obs[b, j]):
                bad = True
                obs[b, j] = obs_low[j]
        if bad:
            diverged[b] = True
            any_bad = True
        ended = failed[b] or diverged[b]
        terminated[b] = ended
        if ended:
            r += steps_left[b] * penalty
            success[b] = False
        rewards[b] = r
        for j in range(obs.shape[1]):
            obs32[b, j] = obs[b, j]
    return any_bad
