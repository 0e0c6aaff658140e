"""The confirmation rule of a candidate that met the stop rule, on fresh starts (the
scoring itself is `agents.scoring.fresh.confirm`, which training hands to its stop).

Three evaluations of 20 episodes at >= 80 % in a row select lucky agents as well as good
ones: a run makes dozens of tries, and the streak it stops on is the first that passed
(an agent whose true rate is 80 % passes three in a row at 26 % of its tries; 70 % at 1.3 %).
So a candidate is scored again, before training stops, on `EPISODES` starts that neither
the training's evaluations nor `agents.check`'s reported episodes use (seeds from `SEED`,
a new block per attempt), with the same code as `agents.evaluate` and `agents.check`
(`agents.scoring.episodes.score`: the same vector env, the model's normalisation statistics
frozen, deterministic actions, the run's LQR hand-over). It is confirmed at `RATE` or more
of them; one that is not does not stop training.

What "solved" then promises, in numbers (`promise()`; scipy.stats.binom): a confirmed
agent succeeded on at least 92 % of 200 fresh starts, so its success rate is at least
87.4 % at 95 % confidence (Wilson's lower bound); an agent whose true rate is 92 % scores
below 80 % on a fresh evaluation of 20 episodes 1.8 % of the time, and over every true
rate, the chance that an agent is confirmed at one attempt and then scores below 80 % on
a fresh 20 is at most 1.1 % (4.1 % for a run that makes ten attempts at the same rate).
"""

from __future__ import annotations

import numpy as np

EPISODES = 200
"""Fresh episodes a candidate is confirmed on (one batched vector env: a few seconds)."""
RATE = 0.92
"""The share of them it must succeed on."""
SEED = 1_000_000
"""The first confirmation seed: attempt k uses SEED + k x EPISODES ... (the training's
evaluations use seed + 10,000 and their envs' own streams, `agents.check` seeds 0..19)."""


def needed(episodes: int | None = None, rate: float | None = None) -> int:
    """Successes a confirmation of `episodes` (default `EPISODES`) needs at `rate`
    (default `RATE`)."""
    episodes = EPISODES if episodes is None else episodes
    return int(np.ceil((RATE if rate is None else rate) * episodes - 1e-9))


def promise(
    episodes: int | None = None, rate: float | None = None, fresh: int = 20, tries: int = 10
) -> dict:
    """The numbers of the module docstring: Wilson's lower bound at the least confirmed
    rate, the chance that an agent of that true rate scores below 80 % on `fresh` episodes,
    and the worst case over true rates of being confirmed and then scoring below 80 %
    (at one attempt, and at `tries` attempts of the same rate)."""
    from scipy.stats import binom, binomtest

    episodes = EPISODES if episodes is None else episodes
    k = needed(episodes, rate)
    below = int(np.ceil(0.8 * fresh)) - 1  # at most this many successes is below 80 %
    p = np.linspace(0.5, 1.0, 5001)
    once = binom.sf(k - 1, episodes, p)
    fails = binom.cdf(below, fresh, p)
    return {
        "wilson_low": binomtest(k, episodes).proportion_ci(method="wilson").low,
        "fresh_below_at_rate": float(binom.cdf(below, fresh, k / episodes)),
        "worst_once": float(np.max(once * fails)),
        "worst_tries": float(np.max((1 - (1 - once) ** tries) * fails)),
    }
