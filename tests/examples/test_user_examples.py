"""The six systems written from the documentation as a new user would (reaction-wheel
pendulum, pendubot, gantry crane, series-elastic joint, planar VTOL, Segway): each model
against an independent derivation by Kane's method (tests/examples/kane.py), energy
conservation without inputs or friction, the Segway's rolling constraints, Gymnasium's and
SB3's checkers, LQR from the task's region, and the examples' list."""

from __future__ import annotations

import importlib

import gymnasium as gym
import numpy as np
import pytest

import dynamics
import examples
from agents.control.policies import ZeroPolicy
from agents.scoring import closed_loop
from examples import gantry_crane, pendubot, planar_vtol, reaction_wheel, segway, series_elastic
from tests.examples import kane
from tests.examples.checkers import assert_both_checkers_pass
from tests.matrix import over

MODULES = {
    m.ID: m for m in (reaction_wheel, pendubot, gantry_crane, series_elastic, planar_vtol, segway)
}
IDS = list(MODULES)
# Each example's env (its fused steps and task functions) is compiled for the checkers and
# the energy episodes alone: 5-8 s of CPU from a cold cache. Two run in the fast suite (an
# input on a wheel; a load hanging in 3D), every one with -m slow; every model stays in the
# fast suite through Kane's method (and the VTOL's energy against Kane's bodies).
STEPPED = over(IDS, fast=(reaction_wheel.ID, gantry_crane.ID))
FRICTIONLESS = {
    "Examples/ReactionWheel-v0": {"b_wheel": 0.0},
    "Examples/Pendubot-v0": {"b1": 0.0, "b2": 0.0},
    "Examples/GantryCrane-v0": {"c": 0.0},
    "Examples/SeriesElastic-v0": {"b_m": 0.0},
}


def _system(module):
    factory = getattr(module, module.TASK.model.__name__)
    return dynamics.Model(factory).compile()


def _random_states(system, rng, k):
    names = system.coordinates
    x = rng.uniform(-np.pi, np.pi, (k, 2 * len(names)))
    x[:, len(names) :] *= 2  # rates up to 2 pi rad/s (or m/s)
    return system.project(x) if system.n_c else x


@pytest.mark.parametrize("env_id", IDS)
def test_each_example_declares_named_reward_terms_and_is_listed(env_id):
    assert MODULES[env_id].TASK.terms  # the one task form: reward terms read inputs by name
    assert examples.ENVS[env_id] == MODULES[env_id].__name__.rsplit(".", 1)[1]
    assert f"{MODULES[env_id].__name__}:{env_id}" in examples.specs()


def test_the_list_names_every_registered_example():
    ids = examples.register_all()
    registered = {k for k in gym.registry if k.startswith("Examples/")}
    assert registered == set(ids)
    for env_id, module in examples.ENVS.items():
        assert importlib.import_module(f"examples.{module}") is not None
        assert env_id in gym.registry


@pytest.mark.parametrize("env_id", IDS)
def test_accelerations_match_kanes_method(env_id):
    """50 random states (on the Segway's rolling constraints) and inputs: the derived q''
    against Kane's method from the bodies and loads. Both solve a linear system of at most
    12 equations in double precision, by different routes (Lagrange's equations with
    multipliers, Kane's equations with dependent speeds), so they agree to round-off:
    measured at most 4e-15 of the accelerations' scale (the pendubot's); 1e-12 leaves a
    margin for other BLAS builds, while a friction coefficient 1 % off moves them by
    1e-4 to 1e-3 of that scale."""
    module = MODULES[env_id]
    system = _system(module)
    ref = getattr(kane, module.__name__.rsplit(".", 1)[1])(dict(system.parameters))
    rng = np.random.default_rng(0)
    x = _random_states(system, rng, 50)
    u = rng.uniform(-5, 5, (50, system.n_u))
    ours = system.accelerations(0.0, x, u)
    theirs = np.array([ref.accelerations(xi, ui) for xi, ui in zip(x, u)])
    scale = max(1.0, np.abs(theirs).max())
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("env_id", [i for i in IDS if i != "Examples/Segway-v0"])
def test_energy_matches_kanes_bodies(env_id):
    """T + V of the spec against the bodies' kinetic energies and the potential of the
    forces Kane's method was given (same zero level): a few evaluations of the same
    polynomial in sines and cosines, so 1e-12 of the energy's scale."""
    module = MODULES[env_id]
    system = _system(module)
    ref = getattr(kane, module.__name__.rsplit(".", 1)[1])(dict(system.parameters))
    x = _random_states(system, np.random.default_rng(1), 20)
    theirs = np.array([ref.energy(xi) for xi in x])
    scale = max(1.0, np.abs(theirs).max())
    np.testing.assert_allclose(system.energy(x), theirs, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("env_id", STEPPED)
def test_both_checkers_pass(env_id):
    assert_both_checkers_pass(env_id)


@pytest.mark.parametrize("env_id", STEPPED)
def test_an_unforced_frictionless_episode_conserves_energy(env_id):
    """No input (the VTOL's thrusts off: action -1; every other input's zero is action 0)
    and no friction: 100 steps of 20 copies, each until it ends (the VTOL falls out of
    its bounds after about a second, a pendulum falls over)."""
    vec = gym.make_vec(env_id, 20, vectorization_mode="vector_entry_point",
                       **FRICTIONLESS.get(env_id, {}))  # fmt: skip
    plant = vec.unwrapped.plant
    action = np.tile(plant.input_to_action(np.zeros(len(plant.task.actuated))), (20, 1))
    _, info = vec.reset(seed=0)
    e0 = info["energy"].copy()
    scale = max(1.0, np.abs(e0).max())
    alive, worst = np.ones(20, dtype=bool), 0.0
    for _ in range(100):
        _, _, term, trunc, info = vec.step(action)
        alive &= ~(term | trunc)
        worst = max(worst, np.abs(info["energy"] - e0)[alive].max(initial=0.0) / scale)
    # DOP853 at each task's substep: measured 1e-12 to 1e-10 of the energy's scale; the
    # bound is the README's "far under 1e-6" with a margin of 10 for the loaded machine
    assert worst < 1e-7


@pytest.mark.slow  # steps the Segway's env (see STEPPED)
def test_the_segway_keeps_its_rolling_constraints():
    """Random torques for 200 steps: each step is projected back onto the three rolling
    constraints, so their residual (m/s) stays at round-off of speeds of order 1 m/s."""
    vec = gym.make_vec(segway.ID, 16, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    vec.action_space.seed(0)
    worst = 0.0
    for _ in range(200):
        _, _, _, _, info = vec.step(vec.action_space.sample())
        worst = max(worst, np.abs(info["constraint_residual"]).max())
    assert worst < 1e-10


def test_the_vtol_thrusts_only_push():
    env = gym.make(planar_vtol.ID)
    env.reset(seed=0)
    plant = env.unwrapped.plant
    mg = 0.5 * 9.81
    np.testing.assert_allclose(plant.action_to_input(np.array([-1.0, 1.0])), [0.0, mg])
    np.testing.assert_allclose(plant.action_to_input(np.array([0.0, 0.0])), [mg / 2, mg / 2])


@pytest.mark.slow
@pytest.mark.parametrize("env_id", IDS)
def test_lqr_holds_the_stated_start_region(env_id):
    """100 seeded episodes from the operating point perturbed within the task's LQR
    region. Zero torque, measured: 0 % everywhere but the crane, whose friction brings a
    trolley started within 0.5 m of its target to rest there with the load still (8 %)."""
    lqr = closed_loop.evaluate_near(env_id, episodes=100, seed=0)
    zero = closed_loop.evaluate_near(env_id, ZeroPolicy, episodes=100, seed=0)
    assert lqr.success_rate >= 0.99
    assert zero.success_rate <= (0.2 if env_id == gantry_crane.ID else 0.0)


@pytest.mark.slow  # plans a 3 s swing-up: about 30 s on an idle machine
def test_the_planner_swings_the_pendubot_up_and_lqr_alone_does_not():
    """From the hanging start, trajectory optimisation + TVLQR succeeds in every episode
    (measured 20 of 20 with agents.check); LQR, linearised upright, diverges."""
    from agents.evaluate import evaluate

    plan = evaluate(pendubot.ID, "plan", episodes=5, seed=0)
    lqr = evaluate(pendubot.ID, "lqr", episodes=5, seed=0)
    assert plan.success_rate == 1.0, plan.summary()
    assert lqr.success_rate == 0.0, lqr.summary()
