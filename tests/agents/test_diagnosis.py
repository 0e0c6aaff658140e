"""The diagnosis of a failed agent, and runs refused for another declaration of the task."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
import yaml

import envs
import examples.furuta  # noqa: F401  (registers Examples/Furuta-v0)
from agents.common import UserError
from agents.evaluate import make_agent
from agents.learning.fingerprint import check_fingerprint, task_fingerprint
from agents.scoring.diagnosis import diagnose, rollout_ends, success_edges

FURUTA = "Examples/Furuta-v0"


@pytest.mark.slow  # three rollouts of four 500-step episodes, about 10 s
def test_the_zero_agent_falls_and_lqr_holds_from_the_same_starts():
    edges = success_edges(FURUTA)
    zero = rollout_ends(make_agent, FURUTA, "zero", 4, 0, edges, "zero")
    assert zero.endings["failure"] == 4  # the pendulum falls past 0.6 rad
    assert np.all(zero.distance > 1) and "theta" in zero.outside
    lqr = rollout_ends(make_agent, FURUTA, "lqr", 4, 0, edges, "lqr")
    assert lqr.endings["success"] == 4 and np.all(lqr.distance <= 1)
    lines = diagnose(make_agent, FURUTA, "zero", 4, 0)
    assert lines[0].startswith("trained: 4 failure") and lines[1].startswith("lqr: 4 success")
    assert any("reward flat inside the success tolerance along theta" in x for x in lines)
    assert any(x.startswith("to try: most episodes end early") for x in lines)
    assert lines[-1].startswith("to try: lqr succeeds from the same starts")


def test_a_changed_declaration_gets_another_fingerprint(tmp_path):
    before = task_fingerprint(FURUTA)
    assert before == task_fingerprint(FURUTA) and task_fingerprint("Pendulum-v1") is None
    task = gym.spec(FURUTA).kwargs["task"]
    changed = dataclasses.replace(task, max_episode_steps=499, name="FurutaChanged")
    envs.register("Test/FurutaChanged-v0", changed)  # not Examples/: that list is checked
    try:
        assert task_fingerprint("Test/FurutaChanged-v0") != before
    finally:
        del gym.registry["Test/FurutaChanged-v0"]
    config = {"env_id": FURUTA, "algo": "ppo", "task": before}
    (tmp_path / "config.yml").write_text(yaml.safe_dump(config))
    check_fingerprint(tmp_path, FURUTA)  # the same declaration: reused
    (tmp_path / "config.yml").write_text(yaml.safe_dump({**config, "task": "0" * 16}))
    with pytest.raises(UserError, match="another declaration of Examples/Furuta-v0"):
        check_fingerprint(tmp_path, FURUTA)


def test_the_diagnosis_says_which_condition_of_the_success_set_is_missed_and_what_to_try():
    # ten episodes end at the goal's angle (inside its 0.05 rad edge) still turning at
    # 0.5 rad/s (the rate's edge 0.1): the position condition is met, the rate's is not
    from agents.scoring.diagnosis import Edges, _ends, advice, describe_ends
    from agents.scoring.episodes import EvalStats

    edges = Edges(("x", "theta", "theta_dot"), np.array([np.inf, 0.05, 0.1]),
                  np.array([np.nan, 0.01, 1e-4]), 1.0, 200, True)  # fmt: skip
    n = 10
    last = np.tile([3.0, 0.01, 0.5], (n, 1))
    last[0, 1] = 0.2  # one ends outside along theta too
    trail = np.repeat(last[:, None, :], 50, axis=1)
    stats = EvalStats(np.zeros(n), np.full(n, 200), np.zeros(n, bool), np.zeros(n, bool))
    ends = _ends("trained", stats, trail, last, edges, None)
    assert ends.within == {"theta": 0.9, "theta_dot": 0.0}  # x: the set does not bound it
    line = describe_ends(ends)
    assert "at the last step within the success edge along theta in 90%, theta_dot in 0%" in line
    tips = advice(ends, {}, ["theta_dot"], edges)
    assert len(tips) == 1 and "does not come to rest (theta_dot" in tips[0]
    lqr = dataclasses.replace(ends, agent="lqr", endings={"success": n})
    assert "lqr succeeds from the same starts" in advice(ends, {"lqr": lqr}, [], edges)[-1]
    # a run that hands over already is not told to declare a hand-over (the acrobot's agent
    # alone at 5 % while the pair succeeds 20 of 20)
    paired = dataclasses.replace(ends, endings={"success": n}, lqr_share=0.82)
    tips = advice(paired, {"lqr": lqr}, [], edges)
    assert not any("declared LQR hand-over" in t for t in tips)
    assert "the hand-over's as much as the agent's (LQR acted in 82% of the steps)" in tips[-1]
