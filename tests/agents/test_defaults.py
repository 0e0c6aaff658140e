"""Learning defaults derived from a task: discount, reward scale, shaping on/off, hand-over
on/off, the flat-reward probe, and the budget's parsing."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs
import examples.furuta  # noqa: F401  (registers Examples/Furuta-v0)
from agents.learning import hparams
from agents.learning.budget import constant_schedules, parse_budget
from agents.learning.defaults import (
    GAMMA_MAX,
    GAMMA_MIN,
    derived,
    describe,
    discount,
    goal_dimensions,
    reward_span,
)
from agents.learning.flat import flat_components, success_edges
from agents.learning.shaping import LQRPotential, TaskRewardVecEnv
from agents.learning.vecenv import make_envs

FURUTA = "Examples/Furuta-v0"
ACROBOT = next(e for e in envs.ENV_IDS if "/Acrobot-" in e)
BEAD = next(e for e in envs.ENV_IDS if "/BeadOnRod-" in e)


def test_discount_looks_a_fifth_of_the_episode_ahead():
    # 500 steps of 20 ms = 10 s; tau = 2 s; gamma = 1 - 0.02 / 2
    assert discount(0.02, 500) == pytest.approx(0.99)
    assert discount(0.05, 200) == pytest.approx(1 - 0.05 / 2.0)
    # the effective horizon 1 / (1 - gamma) is a fifth of the episode, in steps
    assert 1 / (1 - discount(0.01, 400)) == pytest.approx(400 / 5)
    assert discount(0.05, 10) == GAMMA_MIN  # a 0.5 s episode: clipped
    assert discount(0.001, 100_000) == GAMMA_MAX
    with pytest.raises(ValueError, match="positive"):
        discount(0.0, 100)


def test_reward_scale_makes_one_steps_range_one():
    task = gym.spec(FURUTA).kwargs["task"]
    span = reward_span(task)
    assert span == pytest.approx(2 + 0.1 * np.pi**2 + 0.01)  # the terms' declared bounds
    assert derived(FURUTA, task)["reward_scale"] == pytest.approx(1 / span, rel=1e-5)


def test_derived_values_sit_between_the_yaml_default_and_the_task():
    hp = hparams.load("ppo", FURUTA)  # the example declares no hyperparameters
    assert hp["gamma"] == pytest.approx(0.99)
    assert hp["shaping"] == {"lqr": 0.5, "success": 0.1}
    task = gym.spec(ACROBOT).kwargs["task"]
    assert task.hyperparams["ppo"]["gamma"] == 0.998
    acro = hparams.load("ppo", ACROBOT)
    assert acro["gamma"] == 0.998  # the task's own value overrides the derived one
    assert "handover" in acro and acro.get("shaping") is None  # hand-over: its own shaping
    bead = hparams.load("ppo", BEAD)  # declares its budget, measured without shaping
    assert bead.get("shaping") is None and bead["gamma"] == pytest.approx(0.975)


def test_copies_grow_with_the_goals_drawn_for_on_policy_learners_only(tmp_path):
    import examples.three_link_arm as three

    arm = gym.spec(three.ID).kwargs["task"]
    acro = gym.spec(ACROBOT).kwargs["task"]
    assert goal_dimensions(arm) == 3
    assert goal_dimensions(acro) == 0  # its goal (upright) is fixed: low == high
    hp = hparams.load("ppo", three.ID)
    # 4^3 copies, a grid of four goals per component; the minibatch grows alike, so an
    # update takes the YAML default's 8 minibatches per epoch
    assert (hp["n_envs"], hp["batch_size"]) == (64, 2048)
    assert hp["n_envs"] * hp["n_steps"] // hp["batch_size"] == 8
    assert hparams.load("ppo", BEAD)["n_envs"] == 8  # one goal component: the default's 8
    assert "n_envs" not in hparams.load("sac", three.ID)  # off-policy: its own rule
    own = tmp_path / "own.yml"
    own.write_text(f"{three.ID}: {{n_envs: 4}}\n")
    mine = hparams.load("ppo", three.ID, own)
    assert mine["n_envs"] == 4 and mine["batch_size"] == 256  # a declared n_envs stands
    assert "64 copies" in describe(hp)
    # the acrobot declares its 16 copies (a fixed goal would give the default's 8); its
    # minibatch stays the YAML's 256, as it was measured: more minibatches per epoch
    acro_hp = hparams.load("ppo", ACROBOT)
    assert (acro_hp["n_envs"], acro_hp["batch_size"]) == (16, 256)


def test_n_envs_asked_for_keeps_the_minibatches_per_epoch():
    from agents.train import _checked_arguments

    def settings(algo, n_envs):
        hp, _, n, _ = _checked_arguments(BEAD, algo, 1000, n_envs, 10, "auto", None, None)
        return n, hp.get("batch_size")

    n, batch = settings("ppo", None)  # the YAML's 8 copies, 8 minibatches of 256 steps
    assert (n, batch) == (8, 256)
    assert settings("ppo", 2) == (2, 64)  # a quarter of the rollout, a quarter the minibatch
    assert settings("ppo", 32) == (32, 1024)
    sac = hparams.load("sac", BEAD)  # off-policy: its batch is per gradient step, kept
    assert settings("sac", 4)[1] == sac.get("batch_size")


def test_shaping_off_and_on_in_the_training_env():
    hp = {**hparams.load("ppo", BEAD), "shaping": {"lqr": 0.5}}
    train, evaluation = make_envs(BEAD, {**hp, "normalize": False}, 2, 0, "auto", 1)
    assert isinstance(train, TaskRewardVecEnv) and train.potential is not None
    assert isinstance(evaluation, TaskRewardVecEnv) and evaluation.potential is None
    assert evaluation.scale == 1.0  # evaluations score the env's own reward
    train.close(), evaluation.close()
    off = {**hp, "normalize": False, "shaping": {"lqr": 0.0}, "reward_scale": 1.0}
    train, evaluation = make_envs(BEAD, off, 2, 0, "auto", 1)
    assert not isinstance(train, TaskRewardVecEnv)  # nothing to do: not wrapped
    train.close(), evaluation.close()


class _Blinking(gym.Env):
    """Succeeds at every other step: is_success True at steps 2, 4, ..."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,))
    action_space = gym.spaces.Box(-1.0, 1.0, (1,))

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.t += 1
        return np.zeros(1, np.float32), -1.0, False, False, {"is_success": self.t % 2 == 0}


def test_the_success_bonus_is_paid_at_the_steps_inside_the_success_set():
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = TaskRewardVecEnv(DummyVecEnv([_Blinking]), scale=0.5, bonus=0.25)
    venv.reset()
    rewards = [venv.step(np.zeros((1, 1), np.float32))[1][0] for _ in range(4)]
    assert rewards == [-0.5, -0.25, -0.5, -0.25]  # scale x -1, plus the bonus when inside


def test_the_settings_line_names_the_potential_only_where_lqr_can_be_designed():
    hp = {"gamma": 0.99, "shaping": {"lqr": 0.5, "success": 0.1}}
    assert "LQR potential shaping 0.5" in describe(hp)
    line = describe(hp, lqr=False)  # Kapitza's pendulum: time-dependent, LQR refuses
    assert "LQR potential shaping" not in line and "no LQR potential" in line
    assert "success bonus 0.1" in line
    assert "no shaping" in describe({"shaping": {"lqr": 0.5}}, lqr=False)


def test_a_bonus_alone_wraps_the_training_env_and_not_the_evaluation_env():
    hp = {**hparams.load("ppo", BEAD), "normalize": False, "reward_scale": 1.0}
    train, evaluation = make_envs(BEAD, {**hp, "shaping": {"success": 0.1}}, 2, 0, "auto", 1)
    assert isinstance(train, TaskRewardVecEnv) and train.bonus == 0.1
    assert train.potential is None
    assert isinstance(evaluation, TaskRewardVecEnv) and evaluation.bonus == 0.0
    train.close(), evaluation.close()


def test_shaped_reward_is_the_potential_difference():
    hp = {**hparams.load("ppo", BEAD), "normalize": False, "shaping": {"lqr": 0.5}}
    shaped, _ = make_envs(BEAD, hp, 2, 0, "auto", 1)
    plain, _ = make_envs(BEAD, {**hp, "shaping": {"lqr": 0.0}}, 2, 0, "auto", 1)
    phi, gamma, scale = shaped.potential, shaped.gamma, shaped.scale
    obs_s, obs_p = shaped.reset(), plain.reset()
    np.testing.assert_array_equal(obs_s, obs_p)
    for _ in range(5):
        a = np.zeros((2, 1), dtype=np.float32)
        before = phi(obs_s)
        obs_s, r_s, d_s, _ = shaped.step(a)
        obs_p, r_p, d_p, _ = plain.step(a)
        assert not d_s.any()
        # F = gamma Phi(s') - Phi(s), on top of the scaled task reward (float32 rewards)
        expected = r_p + gamma * phi(obs_s) - before
        np.testing.assert_allclose(r_s, expected, rtol=1e-5, atol=1e-5)
        assert plain.scale == pytest.approx(scale)


def test_potential_is_zero_at_the_operating_point_and_half_down_at_a_start():
    phi = LQRPotential(FURUTA, 0.5, 0.99, 500)
    env = gym.make(FURUTA)
    obs = np.array([1.0, 0.0, 1.0, 0.0, 0.0, 0.0])  # alpha = theta = 0, at rest: upright
    assert phi(obs[None])[0] == pytest.approx(0.0, abs=1e-9)
    starts = [env.reset(seed=s)[0] for s in range(64)]
    # V_start is the median cost over these starts, so the median start sits at -W/2; of an
    # even count the median averages two costs, which v / (v + V_start) does not keep exact
    assert np.median(phi(np.stack(starts))) == pytest.approx(-phi.amplitude / 2, rel=1e-3)


def test_potential_falls_linearly_near_the_operating_point():
    # a quadratic potential (V itself) would be as flat at the goal as the users' quadratic
    # rewards: Phi must fall with the distance, so doubling a small offset doubles Phi
    # (a ratio of 4 would be the quadratic's). 1e-4 rad is far inside the Furuta's 0.05 rad
    # success box; the d / (d + 1) saturation bends the ratio to 2 (1 + d) / (1 + 2 d), about
    # 2 (1 - d), with d ~ 2e-3 here (the offset over a typical start's distance, ~0.05 rad).
    phi = LQRPotential(FURUTA, 0.5, 0.99, 500)

    def at(theta):
        return phi(np.array([[1.0, 0.0, np.cos(theta), np.sin(theta), 0.0, 0.0]]))[0]

    assert at(2e-4) / at(1e-4) == pytest.approx(2.0, rel=1e-2)
    assert at(1e-4) < 0.0


def test_flat_reward_probe_finds_the_furutas_flat_angle_and_not_the_arms():
    furuta = success_edges(FURUTA)
    assert furuta.inside
    # success is |theta| < 0.05: the probe's grid edge is the power of 2 below it
    assert furuta.edge[furuta.names.index("theta")] == 2.0**-5
    assert "theta" in flat_components(furuta)  # cos theta is flat within 0.05 rad
    arm = next(e for e in envs.ENV_IDS if "/TwoLinkArm-" in e)
    assert flat_components(success_edges(arm)) == []


@pytest.mark.parametrize(
    "text, seconds", [("600", 600), ("90s", 90), ("10m", 600), ("1.5h", 5400), ("2min", 120)]
)
def test_budget_parses_times(text, seconds):
    assert parse_budget(text) == seconds


@pytest.mark.parametrize("text", ["", "ten minutes", "-5m", "0", "5d"])
def test_budget_refuses_what_is_not_a_time(text):
    with pytest.raises(ValueError, match="expected a"):
        parse_budget(text)


def test_a_budget_run_reads_linear_schedules_as_constants():
    hp = constant_schedules({"learning_rate": "lin_1e-3", "gamma": 0.99, "clip_range": 0.2})
    assert hp == {"learning_rate": 1e-3, "gamma": 0.99, "clip_range": 0.2}


def test_every_algorithm_builds_with_the_derived_settings():
    for algo in hparams.ALGOS:
        hp = hparams.load(algo, FURUTA)
        assert hparams.algo_kwargs(algo, hp, 1)["gamma"] == pytest.approx(0.99)


def test_shaping_is_derived_where_the_operating_point_follows_the_state():
    # the Segway example's operating point rides along its heading (a function of the
    # state): the potential designs LQR row by row there, and is derived as elsewhere
    import examples.segway as segway

    assert callable(segway.TASK.operating_point)
    assert derived(segway.ID, segway.TASK)["shaping"] == {"lqr": 0.5, "success": 0.1}


def test_flat_reward_warning_names_the_remedy_the_training_has():
    from agents.learning.flat import flat_reward_warning

    shaped = flat_reward_warning(FURUTA, shaped=True)
    plain = flat_reward_warning(FURUTA, shaped=False)
    assert "gives it a slope" in shaped and "no LQR shaping" not in shaped
    assert "no LQR shaping" in plain and "gives it a slope" not in plain


@pytest.mark.parametrize(
    "shaping",
    [{"lqr": 0.5, "bonus": 0.1}, {}, {"success": -1.0}, {"success": float("nan")}, 0.5],
)
def test_a_bad_shaping_setting_names_its_form(shaping):
    with pytest.raises(hparams.UserError, match=r"shaping must be \{lqr: W, success: B\}"):
        hparams.check_entries({"shaping": shaping}, "my.yml (default)")
    assert hparams.check_entries({"shaping": {"success": 0.2}}, "f") == {
        "shaping": {"success": 0.2}
    }


def test_training_the_built_ins_prints_no_flat_reward_warning():
    # the crank slider and the bicycle trip the flat-reward probe, and learn without help
    # (98 % and 100 % of 60 episodes, three seeds): training no longer warns before any
    # evidence; the diagnosis of an agent that misses names the flat coordinates
    import warnings

    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.learning.hparams import load_hyperparams
    from agents.learning.vecenv import task_reward

    for env_id in ("Lagrange/CrankSlider-v1", "Lagrange/Bicycle-v0"):
        hp = {**load_hyperparams("ppo", env_id), "shaping": None}
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            task_reward(DummyVecEnv([lambda e=env_id: gym.make(e)]), env_id, hp)


def test_a_command_prints_a_warning_as_a_message(capsys, monkeypatch):
    import sys
    import warnings

    from agents.common import plain_warnings

    monkeypatch.setattr(warnings, "showwarning", warnings.showwarning)
    plain_warnings()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.warn("No LQR shaping for X: LQR refused", UserWarning, stacklevel=1)
    assert capsys.readouterr().err == "warning: No LQR shaping for X: LQR refused\n"
    assert sys.stderr is not None
