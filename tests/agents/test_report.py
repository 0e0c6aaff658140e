"""The main job's statistics: intervals against published values and known coverage, and
findings that claim only what the intervals resolve."""

from __future__ import annotations

import numpy as np
import pytest

import envs
from agents.evaluate import EvalStats, evaluate
from agents.scoring.report import (
    Refused,
    Row,
    Training,
    best_agents,
    compare,
    findings,
    markdown_table,
    mean_interval,
    plot_comparison,
    report_text,
    training_lines,
    wilson_interval,
    write_csv,
)


@pytest.mark.parametrize(
    "k, n, low, high",
    [
        # Newcombe (1998), Statistics in Medicine 17:857, Table I, method 3 (score, no
        # continuity correction): 81/263, 15/148, 0/20, 1/29
        (81, 263, 0.2553, 0.3662),
        (15, 148, 0.0624, 0.1605),
        (0, 20, 0.0, 0.1611),
        (1, 29, 0.0061, 0.1718),
        # 10/20 and 20/20 (the formula by hand: symmetric about 1/2; n/n mirrors 0/n)
        (10, 20, 0.2993, 0.7007),
        (20, 20, 0.8389, 1.0),
    ],
)
def test_wilson_interval_matches_published_values(k, n, low, high):
    ci = wilson_interval(k, n)
    assert (ci.low, ci.high) == pytest.approx((low, high), abs=1e-4)


def test_wilson_interval_holds_the_observed_rate_at_every_count():
    # at 100/100 rounding put the upper end at 1 - 1e-16, and the plot's error bar below
    # the bar (matplotlib refuses negative errors): the interval must contain k / n exactly
    for n in range(1, 201):
        for k in (0, 1, n - 1, n):
            if 0 <= k <= n:
                ci = wilson_interval(k, n)
                assert ci.low <= k / n <= ci.high, (k, n)


def test_wilson_interval_rejects_impossible_counts():
    with pytest.raises(ValueError, match="0 <= successes <= n"):
        wilson_interval(21, 20)


@pytest.mark.parametrize(
    "draw, mean, coverage",
    [
        (lambda rng, size: rng.normal(3.0, 2.0, size), 3.0, (0.94, 0.96)),  # exact for normal
        # skewed: the t interval undercovers a little at n = 20 (it is still the better of
        # t and percentile bootstrap here, see agents.scoring.report)
        (lambda rng, size: rng.exponential(1.0, size), 1.0, (0.89, 0.93)),
    ],
)
def test_return_interval_covers_the_true_mean_at_its_level(draw, mean, coverage):
    rng = np.random.default_rng(12345)
    samples = draw(rng, (4000, 20))
    hits = [(ci.low <= mean <= ci.high) for ci in map(mean_interval, samples)]
    assert coverage[0] <= np.mean(hits) <= coverage[1]


def test_return_interval_of_one_episode_is_unbounded():
    ci = mean_interval([1.0])
    assert ci.low == -np.inf and ci.high == np.inf


def stats(successes: int, returns, n: int = 20) -> EvalStats:
    returns = np.broadcast_to(np.asarray(returns, dtype=float), (n,)).copy()
    won = np.arange(n) < successes
    return EvalStats(returns, np.full(n, 200), won, np.zeros(n, bool), np.zeros(n, bool))


def spread(centre: float, width: float = 1.0, n: int = 20) -> np.ndarray:
    return centre + width * np.linspace(-1.0, 1.0, n)


def test_beats_is_said_only_where_the_intervals_separate():
    # success 20/20 [0.84, 1] against 10/20 [0.30, 0.70]: separated
    assert compare("lqr", stats(20, spread(0)), "ppo", stats(10, spread(0))).startswith(
        "lqr beats ppo on success rate (100% [84%, 100%] vs 50% [30%, 70%])"
    )
    # 18/20 [0.70, 0.97] against 14/20 [0.48, 0.85]: overlap; returns overlap too
    text = compare("lqr", stats(18, spread(0)), "ppo", stats(14, spread(0.2)))
    assert "beats" not in text and "not resolved at 20 episodes" in text
    # success overlaps, returns well apart: the claim names the return
    text = compare("lqr", stats(18, spread(-5)), "ppo", stats(14, spread(-50)))
    assert text.startswith("lqr beats ppo on return (-5.0 [") and "success rate" not in text
    # opposite verdicts on the two measures are both said
    text = compare("a", stats(20, spread(-50)), "b", stats(0, spread(-5)))
    assert "a beats b on success rate" in text and "b beats a on return" in text


def test_best_agents_are_those_nothing_beats():
    mine = {
        "random": stats(0, spread(-1000)),
        "lqr": stats(20, spread(-10, 5)),
        "heuristic": stats(20, spread(-11, 5)),
        "ppo": stats(12, spread(-12)),
    }
    assert best_agents(mine) == ["lqr", "heuristic"]
    assert best_agents({"a": stats(20, spread(-1)), "b": stats(5, spread(-1))}) == ["a"]


def diverging_and_failing() -> EvalStats:
    n = 6
    success = np.array([1, 1, 0, 0, 0, 0], bool)
    terminated = np.array([0, 0, 1, 1, 1, 0], bool)
    diverged = np.array([0, 0, 1, 0, 0, 0], bool)
    return EvalStats(np.arange(n, dtype=float), np.full(n, 10), success, terminated, diverged)


def test_endings_count_each_episode_once():
    ends = diverging_and_failing().endings()
    assert ends == {"success": 2, "failure": 2, "diverged": 1, "time limit": 1}
    legacy = EvalStats(np.zeros(3), np.full(3, 5), np.array([1, 0, 0], bool))
    assert legacy.endings() == {"success": 1, "failure": 0, "diverged": 0, "time limit": 2}


class FullTorque:
    """Both motors at +1 throughout: the arm spins up until its rates pass their bound."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.ones((len(observation), 2), dtype=np.float32), None


def test_evaluation_records_how_each_episode_ended():
    arm = next(env_id for env_id in envs.ENV_IDS if "/TwoLinkArm-" in env_id)
    spun = evaluate(arm, FullTorque(), episodes=3)
    assert spun.endings() == {"success": 0, "failure": 0, "diverged": 3, "time limit": 0}
    assert (spun.lengths < 200).all()
    assert evaluate(arm, "zero", episodes=3).endings()["time limit"] == 3
    assert evaluate(arm, "lqr", episodes=3).endings()["success"] == 3


def rows_like_the_arm() -> list[Row]:
    """TwoLinkArm's sample: three good agents near -100, two baselines far below."""
    rng = np.random.default_rng(0)

    def run(k, mean, std):
        return stats(k, rng.normal(mean, std, 20))

    training = Training("ppo", 100_000, 100_352, 201.0, 100_352, "train/arm/ppo_seed0")
    return [
        Row("Lagrange/TwoLinkArm-v1", "random", run(0, -1102, 585), 1.0),
        Row("Lagrange/TwoLinkArm-v1", "zero", run(0, -1952, 436), 0.1),
        Row("Lagrange/TwoLinkArm-v1", "heuristic", run(20, -78, 40), 0.2, "PD"),
        Row("Lagrange/TwoLinkArm-v1", "lqr", run(20, -100, 65), 1.3),
        Row("Lagrange/TwoLinkArm-v1", "ppo", run(18, -103, 64), 0.5, "", training),
        Row("Lagrange/CrankSlider-v1", "lqr", run(20, -3.3, 3.3), 0.9),
        Row("Lagrange/CrankSlider-v1", "ppo", diverging_and_failing(), 0.4),
    ]


def test_table_csv_and_header_lines(tmp_path):
    rows = rows_like_the_arm()
    table = markdown_table(rows).splitlines()
    assert "ended: success | failure | diverged | time limit" in table[0]
    assert len({line.count("|") for line in table}) == 1  # every row has every column
    last = table[-1]
    assert "| Lagrange/CrankSlider-v1 | ppo | 33% [" in last and "| 2 | 2 | 1 | 1 |" in last
    assert training_lines(rows) == [
        "Lagrange/TwoLinkArm-v1: PPO, 100,000 steps (100,352 trained in 201 s; "
        "[learning curve](train/arm/ppo_seed0/learning_curve.png))"
    ]
    write_csv(rows, tmp_path / "r.csv")
    header, *lines = (tmp_path / "r.csv").read_text().splitlines()
    assert len(lines) == len(rows) and "success_low" in header and "n_diverged" in header
    text = "\n".join(findings(rows))
    assert "Lagrange/TwoLinkArm-v1:\n  - best, not resolved between them" in text


def test_agents_not_run_are_in_the_table_and_csv_with_their_reason(tmp_path):
    rows = rows_like_the_arm()
    refused = [Refused("Lagrange/TwoLinkArm-v1", "plan", "the task declares no | plan\nhere")]
    table = markdown_table(rows, refused).splitlines()
    cells = {line.replace("\\|", "").count("|") for line in table}  # an escaped | is no cell
    assert len(cells) == 1  # every row has every column
    arm = [i for i, line in enumerate(table) if "TwoLinkArm" in line]
    assert table[arm[-1]].startswith("| Lagrange/TwoLinkArm-v1 | plan | not run |")
    assert table[arm[-1]].endswith(" the task declares no \\| plan here |")  # after its env
    write_csv(rows, tmp_path / "r.csv", refused)
    last = (tmp_path / "r.csv").read_text().splitlines()[-1]
    assert last.startswith("Lagrange/TwoLinkArm-v1,plan,,") and "not run: the task" in last
    assert "| plan | not run |" in report_text(rows, 20, 0, 1.0, refused)


def test_comparison_figure_is_written(tmp_path):
    plot_comparison(rows_like_the_arm(), tmp_path / "comparison.png")
    assert (tmp_path / "comparison.png").stat().st_size > 10_000
