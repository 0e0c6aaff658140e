"""A user's declaration is checked where it is made, its functions cannot corrupt the runtime,
and what no agent can do right is refused (time-dependent dynamics, unobserved coordinates).

One test per mechanism; the malformed declarations are a table, each entry with the field
its error must name."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from gymnasium.utils.env_checker import check_env

import envs
from agents.control.lqr_policy import LQRPolicy
from agents.control.tvlqr import PlanPolicy
from dynamics.spec import ModelSpec, Param
from envs.checks import DeclarationError
from envs.docs import describe
from examples import cart_pole, kapitza  # noqa: F401  (registers Kapitza-v0)

BASE = cart_pole.TASK


def _swap(**changes):
    return lambda: dataclasses.replace(BASE, **changes)


def _term(fn, low=-1.0, high=1.0, name="upright"):
    return (envs.Term(name, low, high, "", fn), *BASE.terms[1:])


def nan_term(x, a, goal, p):
    return x.x * np.nan


def one_term(x, a, goal, p):
    return 1.0


def float_success(x, a, goal, p):
    return np.abs(x.theta) * 1.0


def typo_column(x, a, goal, p):
    return np.cos(x.thetaa)


def in_place(x, a, goal, p):
    err = x.x
    err -= 0.5  # meant: err = x.x - 0.5
    return err


def wide_column(x, a, g, p):  # the former form, reading a column the state does not have
    return np.cos(x[:, 7]), np.zeros(len(x)), np.zeros(len(x))


def _former(reward):
    terms = tuple(dataclasses.replace(t, fn=None) for t in BASE.terms)
    return lambda: dataclasses.replace(BASE, reward=reward, terms=terms)


# (declaration, the words its error must contain: the field and the entry)
MALFORMED_AT_TASK = {
    "no input": (_swap(actuated=()), "`actuated`"),
    "input twice": (_swap(actuated=("F", "F")), "names ['F'] more than once"),
    "too few limits": (_swap(max_input=(1.0, 2.0)), "`max_input` needs one limit"),
    "negative limit": (_swap(max_input=(-1.0,)), "`max_input['F']` must be positive"),
    "inverted asymmetric limit": (_swap(max_input=((2.0, 1.0),)), "above high"),
    "empty observation": (_swap(observation=()), "`observation`"),
    "not a feature": (_swap(observation=("x",)), "`observation[0]` is not a feature"),
    "repeated term": (_swap(terms=BASE.terms[:1] * 2), "named once each"),
    "infinite bound": (
        _swap(terms=(envs.Term("upright", -np.inf, 1.0, "", cart_pole.upright), *BASE.terms[1:])),
        "`terms (upright)` must be finite",
    ),
    "term without fn": (_swap(terms=(envs.Term("upright", -1, 1),)), "need a function"),
    "reward and fns": (_swap(reward=cart_pole.upright), "`reward=`"),
    "former reward form": (_former(wide_column), "fn=upright)` with `def upright(x, a, goal, p)"),
    "success not callable": (_swap(success=True), "`success` must be a function"),
    "start inverted": (_swap(start={"x": (0.5, -0.5)}), "`start['x']` has low 0.5 above high"),
    "start not a pair": (_swap(start={"x": 0.5}), "`start['x']` must be a (low, high) pair"),
    "limit zero": (_swap(limits={"x": 0.0}), "`limits['x']` must be positive"),
    "no steps": (_swap(max_episode_steps=0), "`max_episode_steps` must be positive"),
    "float steps": (_swap(max_episode_steps=2.5), "`max_episode_steps` must be an integer"),
    "negative period": (_swap(control_period=-0.02), "`control_period` must be positive"),
    "integrator typo": (_swap(integrator="dop835"), "Did you mean 'dop853'"),
    "algo typo": (_swap(algo="ppo2"), "`algo` must be one of"),
    "hyperparams typo": (_swap(hyperparams={"pp0": {}}), "Did you mean 'ppo'"),
    "lqr scale zero": (_swap(lqr=envs.LQRHints(scales={"x": 0.0})), "`lqr.scales['x']`"),
    "heuristic target": (
        _swap(heuristic=envs.Heuristic("pd", "agents.control.policies.PD")),
        "'module:Class'",
    ),
}

MALFORMED_AT_MAKE = {
    "start beyond limit": (
        _swap(start={"x": (-5.0, 5.0)}),
        "`start['x']` = (-5, 5) reaches beyond",
    ),
    "lqr scale typo": (_swap(lqr=envs.LQRHints(scales={"thetaa": 0.1})), "Did you mean 'theta'"),
    "lqr region typo": (_swap(lqr=envs.LQRHints(region={"x_dott": 0.1})), "`lqr.region`"),
    "operating point typo": (_swap(operating_point={"thetaa": 0.0}), "`operating_point`"),
    "operating point goal typo": (
        _swap(operating_point={"x": "x_star"}),
        "`operating_point['x']` names 'x_star', neither a goal component nor a parameter",
    ),
    "constants shadow": (_swap(constants=lambda s: {"g": 1.0}), "shadow parameters"),
    "constant not a number": (_swap(constants=lambda s: {"k": "big"}), "`constants['k']`"),
    "unknown input": (_swap(actuated=("G",)), "actuates 'G'"),
    "term NaN": (_swap(terms=_term(nan_term)), "term 'upright' (nan_term) gives NaN"),
    "term scalar": (_swap(terms=_term(one_term)), None),  # accepted: broadcast to every row
    "success float": (_swap(success=float_success), "must give booleans"),
    "typo in a column name": (_swap(terms=_term(typo_column)), "term 'upright' (typo_column)"),
    "edits its input": (_swap(terms=_term(in_place)), "writes into its inputs"),
    "start function NaN": (
        _swap(start=lambda rng, p: ({"x": np.nan}, {})),
        "`start` must return a finite state",
    ),
}


@pytest.mark.parametrize("case", MALFORMED_AT_TASK)
def test_a_declaration_wrong_on_its_own_fails_at_Task_naming_the_field(case):
    make, words = MALFORMED_AT_TASK[case]
    with pytest.raises((ValueError, TypeError)) as err:
        make()
    assert words in str(err.value)
    assert "CartPole" in str(err.value) or "max_input" in str(err.value)


@pytest.mark.parametrize("case", MALFORMED_AT_MAKE)
def test_a_declaration_wrong_for_its_model_fails_at_make_naming_the_field(case):
    make, words = MALFORMED_AT_MAKE[case]
    task = make()
    if words is None:  # documented as accepted: a scalar term applies to every row
        envs.LagrangianEnv(task).reset(seed=0)
        return
    with pytest.raises((ValueError, TypeError, IndexError)) as err:
        envs.LagrangianEnv(task)
    assert words in str(err.value), str(err.value)


def test_an_operating_point_no_input_can_hold_is_refused_with_its_size():
    # the cart pole tilted 0.3 rad: gravity tips it, and the cart force cannot hold it
    env = envs.LagrangianEnv(dataclasses.replace(BASE, operating_point={"theta": 0.3}))
    env.reset(seed=0)
    with pytest.raises(DeclarationError, match="no equilibrium: .* accelerations of up to"):
        env.operating_point()


def test_an_input_that_moves_nothing_is_refused():
    th = me.dynamicsymbols("theta")
    m, l, g, tau, idle = *sp.symbols("m l g", positive=True), *sp.symbols("tau idle")
    params = {m: Param(1.0, "kg"), l: Param(1.0, "m"), g: Param(9.81, "m/s^2")}
    spec = ModelSpec(
        "idle_pendulum", (th,), m * l**2 * th.diff() ** 2 / 2, -m * g * l * sp.cos(th),
        params, (tau, idle), {th: tau},
    )  # fmt: skip
    task = dataclasses.replace(
        BASE, model=lambda: spec, actuated=("idle",), max_input=(1.0,),
        observation=(envs.Angle("theta"),), terms=(envs.Term("e", -1, 0, "", _effort_idle),),
        success=_never, failure=None, start={}, limits={}, operating_point={},
        lqr=envs.LQRHints(),
    )  # fmt: skip
    with pytest.raises(DeclarationError, match="drives 'idle', which appears in no generalised"):
        envs.LagrangianEnv(task)


def _effort_idle(x, a, goal, p):
    return -(a.idle**2)


def _never(x, a, goal, p):
    return x.theta > 10.0


def test_a_foreign_time_symbol_is_refused():
    th = me.dynamicsymbols("theta")
    t_real = sp.Symbol("t", real=True)  # not the time the derivation differentiates by
    m = sp.Symbol("m", positive=True)
    with pytest.raises(ValueError, match="potential uses a time symbol t .*dynamics.spec.t"):
        ModelSpec("driven", (th,), m * th.diff() ** 2 / 2, sp.cos(th - t_real), {m: Param(1, "kg")})


# ---- the runtime's buffers are safe from task functions ------------------------------------
SLIP = textwrap.dedent(
    """
    import dataclasses, numpy as np, envs
    from examples import cart_pole

    def far(x, a, goal, p):
        return np.cos(x.theta[50_000_000]) + 0.0 * x.theta

    first, *rest = cart_pole.TASK.terms
    task = dataclasses.replace(cart_pole.TASK, terms=(dataclasses.replace(first, fn=far), *rest))
    try:
        envs.LagrangianEnv(task)
    except IndexError as exc:
        print("IndexError:", exc)
    """
)


@pytest.mark.slow
def test_an_index_far_out_of_range_is_an_error_not_a_crash():
    # in a subprocess: unchecked, numba read 400 MB past the buffer and the process died
    out = subprocess.run([sys.executable, "-c", SLIP], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "IndexError: Task 'CartPole': term 'upright' (far) indexes beyond" in out.stdout


def late_nan(x, a, goal, p):  # finite on the sample rows (|x| < 0.5), NaN past 0.6 m
    return np.where(np.abs(x.x) > 0.6, np.nan, np.cos(x.theta))


def test_a_term_that_turns_nan_later_ends_the_episode_as_divergence():
    env = envs.LagrangianEnv(dataclasses.replace(BASE, terms=_term(late_nan)))
    env.reset(seed=0, options={"state": [0.55, 0.0, 1.0, 0.0]})
    for _ in range(50):
        obs, reward, terminated, truncated, info = env.step(np.zeros(1, np.float32))
        assert np.isfinite(reward) and np.isfinite(obs).all()
        if terminated:
            break
    assert terminated and info["diverged"]
    assert info["reward_terms"]["upright"] == -1.0  # the term's lower bound


def test_the_early_end_penalty_counts_the_limit_given_to_make():
    # a failure at step k pays (limit - k) x the lowest reward: the limit is the env's own
    for limit in (50, 200):
        env = gym.make("Lagrange/BeadOnRod-v1", max_episode_steps=limit)
        env.reset(seed=0)
        steps, lowest = 0, env.unwrapped.plant.lowest_reward
        while True:
            _, reward, terminated, truncated, info = env.step(np.ones(1, np.float32))
            steps += 1
            if terminated or truncated:
                break
        assert terminated and not info["diverged"]  # the bead left the rod
        own = sum(info["reward_terms"].values())
        assert reward == pytest.approx(own + (limit - steps) * lowest, rel=1e-12)


def test_asymmetric_input_limits():
    # a thruster that only pushes: action -1 is no force, 1 is 10 N
    env = envs.LagrangianEnv(dataclasses.replace(BASE, max_input=((0.0, 10.0),)))
    env.reset(seed=0)
    assert env.action_to_input([-1.0])[0] == 0.0 and env.action_to_input([1.0])[0] == 10.0
    _, _, _, _, info = env.step(np.array([-1.0], np.float32))
    assert info["input"][0] == 0.0
    assert "| 0 | F | 0 | 10 |" in describe(env.task)
    assert env.input_to_action(env.action_to_input([0.3])) == pytest.approx([0.3])


def test_registering_an_id_again_with_another_task_warns():
    envs.register("Test/Reregister-v0", BASE)
    envs.register("Test/Reregister-v0", BASE)  # the same task: nothing to say
    with pytest.warns(UserWarning, match="registered already with another task"):
        envs.register("Test/Reregister-v0", dataclasses.replace(BASE, max_episode_steps=10))
    assert gym.spec("Test/Reregister-v0").kwargs["task"].max_episode_steps == 10


# ---- what agents cannot do right is refused ------------------------------------------------
def test_lqr_refuses_a_time_dependent_system():
    env = gym.make("Examples/Kapitza-v0")
    check_env(env.unwrapped)  # a time-dependent env is an env like any other
    assert env.unwrapped.plant.time_dependent
    assert not gym.make("Examples/CartPole-v0").unwrapped.plant.time_dependent
    with pytest.raises(ValueError, match="LQR designs on the dynamics at one time"):
        LQRPolicy(env)
    with pytest.raises(ValueError, match="The plan tracker designs .* time-dependent"):
        PlanPolicy(env)


def test_agents_that_rebuild_the_state_refuse_an_unobserved_coordinate():
    # the cart position left out: LQR would regulate a cart it believes at 0
    observation = tuple(f for f in BASE.observation if getattr(f, "name", "") != "x")
    env = envs.LagrangianEnv(dataclasses.replace(BASE, observation=observation))
    assert env.plant.unobserved == ("x",)
    with pytest.raises(ValueError, match=r"LQR rebuilds .* does not observe \['x'\]"):
        LQRPolicy(env)
    with pytest.raises(ValueError, match=r"The plan tracker rebuilds .* does not observe \['x'\]"):
        PlanPolicy(env)
    # regulating only what is observed is fine
    LQRPolicy(env, states=("theta", "x_dot", "theta_dot"))
