"""A candidate of the stop rule scored on fresh starts (`agents.learning.confirm` states the
rule and what it promises), with the same code as `agents.evaluate` and `agents.check`."""

from __future__ import annotations

import time

import numpy as np

from ..learning import confirm as rule
from .episodes import score
from .report import wilson_interval
from .trained import SB3Policy, with_handover


def confirm(model, env_id: str, hp: dict, attempt: int, episodes: int | None = None) -> dict:
    """Score `model` (as it is now, with its statistics and the run's hand-over) on
    `episodes` fresh starts, seeds rule.SEED + attempt x episodes onwards; a record with the
    successes, the rate, Wilson's 95 % interval, the seeds, the seconds and `passed`."""
    episodes = rule.EPISODES if episodes is None else int(episodes)
    first = rule.SEED + attempt * episodes
    start = time.perf_counter()
    policy = SB3Policy.of_model(model, hp.get("handover"), hp.get("feedforward"))
    stats = score(env_id, lambda venv: with_handover(policy, venv), episodes, first)
    k = int(np.sum(stats.successes))
    interval = wilson_interval(k, episodes)
    return {
        "episodes": episodes,
        "successes": k,
        "rate": round(k / episodes, 4),
        "wilson95": [round(interval.low, 4), round(interval.high, 4)],
        "seeds": [first, first + episodes - 1],
        "needed": rule.needed(episodes),
        "passed": k >= rule.needed(episodes),
        "seconds": round(time.perf_counter() - start, 2),
    }
