"""Perturbations (`perturb=`): off by default and then nothing changes; each perturbation
does what it declares, seeded from the env's seed alike in single and vector envs; bad
declarations are refused with errors naming the problem."""

from __future__ import annotations

import inspect
import pickle

import gymnasium as gym
import numpy as np
import pytest

import envs
from tests.binding import bound
from tests.matrix import over

ARM, ACROBOT = "Lagrange/TwoLinkArm-v1", "Lagrange/Acrobot-v2"
# the arm's perturbed steps by default (each model's pushed lanes are compiled for these
# tests alone: the disk's 7 s of CPU cold), every model's with -m slow; the disk's perturbed
# fused step is checked by default against its recording (tests/envs/test_recorded.py)
PERTURBED_IDS = over(envs.ENV_IDS, fast=("Lagrange/TwoLinkArm-v1",))
PUSH = {"force": 8.0, "every": 0.3, "duration": 0.1}
ALL = {"obs_noise": 0.02, "action_noise": 0.3, "motor_k": 0.6, "delay": 2, "push": PUSH}
NEUTRAL = {
    "obs_noise": 0.0,
    "action_noise": 0.0,
    "motor_k": 1.0,
    "delay": 0,
    "push": {"force": 0.0, "every": 0.1},
}


def _vec(env_id, n, **kwargs):
    return gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)


def _actions(env, k, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (k, *env.action_space.shape)).astype(np.float32)


def _rollout(env, actions, seed):
    """(observations, rewards, states, inputs) of one episode's first len(actions) steps."""
    obs, info = env.reset(seed=seed)
    out = [[obs], [], [info["state"]], [info["input"]]]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        for lst, v in zip(out, (obs, r, info["state"], info["input"])):
            lst.append(v)
        if term or trunc:
            break
    return [np.array(v) for v in out]


# ---- off by default ---------------------------------------------------------------------
@pytest.mark.parametrize("value", [None, {}])
def test_off_by_default_keeps_the_fused_step(value):
    for env in (gym.make(ARM, perturb=value).unwrapped, _vec(ARM, 3, perturb=value).unwrapped):
        assert env._rt.perturber is None
        assert env._rt.stepper.fused is not None
        assert "applied" not in inspect.getsource(env._rt.stepper.fused.py_func)


@pytest.mark.parametrize("env_id", PERTURBED_IDS)
@pytest.mark.parametrize("fused", [True, False])
def test_neutral_perturbations_step_bit_for_bit_like_none(env_id, fused):
    """Zero noise, k = 1, no delay and pushes of no force take the perturbed path (the
    perturbed fused step, or the separate calls; the integrator that adds generalised
    forces) and change nothing: the hooks are exact identities."""
    plain = gym.make(env_id).unwrapped
    neutral = gym.make(env_id, perturb=NEUTRAL).unwrapped
    assert neutral._rt.perturber is not None and plain._rt.perturber is None
    if fused:
        bound(neutral)
    else:
        neutral._rt.stepper.separate()  # the step of separate calls
    actions = _actions(plain, 30)
    for a, b in zip(_rollout(plain, actions, 5), _rollout(neutral, actions, 5)):
        assert np.array_equal(a, b)


def test_neutral_perturbations_change_no_row_of_a_vector_env():
    """Nine rows: the pushed integrator's vector lanes (eight rows and more)."""
    plain, neutral = _vec(ACROBOT, 9), _vec(ACROBOT, 9, perturb=NEUTRAL)
    bound(neutral)
    plain.reset(seed=3), neutral.reset(seed=3)
    for a in _actions(plain, 20):
        for x, y in zip(plain.step(a)[:4], neutral.step(a)[:4]):
            assert np.array_equal(x, y)


def test_the_simulator_agents_use_is_nominal():
    env = gym.make(ARM, perturb=ALL).unwrapped
    assert env._rt.perturber is not None
    assert env.simulator(4).perturber is None  # controllers keep the nominal model


# ---- seeding -------------------------------------------------------------------------------
def test_start_states_are_those_of_the_unperturbed_env():
    """The perturbations' generators are spawned from the reset generator, which they
    leave as it was: every episode starts where the unperturbed env's does."""
    plain, perturbed = gym.make(ACROBOT), gym.make(ACROBOT, perturb=ALL)
    for seed in (1, None, None):
        _, i1 = plain.reset(seed=seed)
        _, i2 = perturbed.reset(seed=seed)
        assert np.array_equal(i1["state"], i2["state"])


@pytest.mark.parametrize("env_id", [ARM, ACROBOT])
def test_a_vector_copy_is_perturbed_like_a_single_env_with_its_seed(env_id):
    """Copy i of a vector env reset with seed s steps bit for bit like a single env reset
    with s + i, across an autoreset (the copy's next episode draws from a generator
    spawned anew, as the single env's next reset does)."""
    n, row, limit = 3, 2, 12
    vec = _vec(env_id, n, perturb=ALL, max_episode_steps=limit)
    single = gym.make(env_id, perturb=ALL, max_episode_steps=limit)
    actions = _actions(single, 2 * limit, seed=1)  # to the end of the second episode
    obs, info = vec.reset(seed=7)
    o1, i1 = single.reset(seed=7 + row)
    assert np.array_equal(obs[row], o1)
    for k, a in enumerate(actions):
        batch = np.zeros((n, *a.shape), np.float32)
        batch[row] = a
        obs, r, term, trunc, info = vec.step(batch)
        if k == limit:  # NEXT_STEP: this step reset the copy that finished
            o1, i1 = single.reset()
            assert np.array_equal(obs[row], o1)
            continue
        o1, r1, t1, tr1, i1 = single.step(a)
        assert np.array_equal(obs[row], o1) and r[row] == r1
        assert np.array_equal(info["input"][row], i1["input"])
        assert (term[row], trunc[row]) == (t1, tr1)


def test_seeded_runs_repeat_and_seeds_differ():
    env = gym.make(ARM, perturb=ALL)
    actions = _actions(env, 20)
    a, b, c = (_rollout(env, actions, s) for s in (3, 3, 4))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[3], c[3])


def test_a_pickled_env_goes_on_alike():
    env = gym.make(ARM, perturb=ALL).unwrapped
    env.reset(seed=2)
    for a in _actions(env, 5):
        env.step(a)
    twin = pickle.loads(pickle.dumps(env))
    for a in _actions(env, 10, seed=3):
        o1, *_ = env.step(a)
        o2, *_ = twin.step(a)
        assert np.array_equal(o1, o2)


# ---- what each perturbation does --------------------------------------------------------
def _inputs(perturb, commands, env_id=ARM):
    """The applied inputs (info['input'], actuated columns) under a sequence of actions."""
    env = gym.make(env_id, perturb=perturb).unwrapped
    env.reset(seed=0)
    rows = []
    for a in commands:
        rows.append(env.step(a)[4]["input"][env.plant.actuated])
    return env, np.array(rows)


def test_delay_applies_the_command_of_d_periods_before_and_zero_until_then():
    env = gym.make(ARM).unwrapped
    commands = _actions(env, 12)
    env, u = _inputs({"delay": 3}, commands)
    commanded = env.action_to_input(commands)[:, env.plant.actuated]
    assert np.array_equal(u[:3], np.zeros((3, 2)))
    assert np.array_equal(u[3:], commanded[:-3])


def test_the_motor_response_follows_its_recursion_and_stays_within_the_limits():
    env = gym.make(ARM).unwrapped
    commands = np.tile(np.array([[1.0, -0.5]], np.float32), (8, 1))
    commanded = env.action_to_input(commands)[:, env.plant.actuated]
    for k in (0.3, 1.7, 2.0):
        env, u = _inputs({"motor_k": k}, commands)
        state, expected = np.zeros(2), []
        for c in commanded:
            state = state + k * (c - state)  # the lag's own state is unclipped
            expected.append(np.clip(state, env.plant.input_low, env.plant.input_high))
        assert np.array_equal(u, np.array(expected))
        assert (u >= env.plant.input_low).all() and (u <= env.plant.input_high).all()


def test_motor_k_per_input_and_reset_clears_the_motor_and_the_delay_line():
    env = gym.make(ARM, perturb={"motor_k": [0.5, 1.0], "delay": 1}).unwrapped
    command = np.array([1.0, 1.0], np.float32)
    full = env.action_to_input(command)[env.plant.actuated]
    for _ in range(2):  # the second episode starts afresh
        env.reset(seed=0)
        u1 = env.step(command)[4]["input"][env.plant.actuated]
        u2 = env.step(command)[4]["input"][env.plant.actuated]
        assert np.array_equal(u1, [0.0, 0.0])
        assert np.array_equal(u2, [0.5 * full[0], full[1]])


def test_action_noise_has_the_declared_size_per_input():
    """Zero commands: the applied input is the noise (clipped to limits it never reaches
    at these sizes); 4,000 samples estimate a std to about 1.1 %, so 5 % is a bound the
    estimate misses with probability below 1e-5."""
    std = np.array([0.3, 1.2])
    vec = _vec(ARM, 200, perturb={"action_noise": std})
    vec.reset(seed=0)
    zero = np.zeros(vec.action_space.shape, np.float32)
    act = vec.unwrapped.plant.actuated
    u = np.concatenate([vec.step(zero)[4]["input"][:, act] for _ in range(20)])
    assert np.allclose(u.std(axis=0), std, rtol=0.05)
    assert np.abs(u.mean(axis=0) / std).max() < 0.1  # the mean's std is 1.6 % of std


def test_observation_noise_has_its_size_stays_in_the_space_and_leaves_the_physics():
    """The noisy observation is the true one plus the declared noise, clipped into the
    observation space; the state and reward are the unperturbed env's bit for bit."""
    std = 0.05
    plain, noisy = gym.make(ARM), gym.make(ARM, perturb={"obs_noise": std})
    space = noisy.observation_space
    actions = _actions(plain, 60)
    p, q = _rollout(plain, actions, 9), _rollout(noisy, actions, 9)
    assert np.array_equal(p[1], q[1]) and np.array_equal(p[2], q[2])  # rewards, states
    assert all(space.contains(o) for o in q[0])
    inside = (np.abs(p[0]) < 1 - 4 * std) & (space.high < 1e3)  # far from the clipping
    noise = (q[0] - p[0])[inside]
    # ~500 samples: the std estimate's own std is 3 %; 15 % is five of them
    assert abs(noise.std() / std - 1) < 0.15
    wild = gym.make(ARM, perturb={"obs_noise": 10.0})  # mostly clipped, still inside
    obs, _ = wild.reset(seed=0)
    for a in actions[:10]:
        assert wild.observation_space.contains(obs)
        obs = wild.step(a)[0]


# ---- declarations ------------------------------------------------------------------------
@pytest.mark.parametrize(
    "perturb, error",
    [
        ({"obs_nosie": 0.1}, "Did you mean 'obs_noise'"),
        ({"obs_noise": -0.1}, ">= 0"),
        ({"action_noise": [0.1, 0.2, 0.3]}, "one per actuated input \\(2\\)"),
        ({"obs_noise": [0.1, 0.2]}, "one per observation feature"),
        ({"action_noise": float("nan")}, "finite"),
        ({"motor_k": 0.0}, "\\(0, 2\\]"),
        ({"motor_k": 2.5}, "\\(0, 2\\]"),
        ({"motor_k": [1.0, -1.0]}, "\\(0, 2\\]"),
        ({"delay": 1.5}, "int >= 0"),
        ({"delay": -1}, "int >= 0"),
        ({"delay": True}, "int >= 0"),
        ({"push": {"every": 1.0}}, "needs 'force'"),
        ({"push": {"force": 1.0, "evry": 1.0}}, "Did you mean 'every'"),
        ({"push": {"force": -1.0}}, ">= 0"),
        ({"push": {"force": 1.0, "duration": 0}}, "> 0"),
        ({"push": {"force": 1.0, "point": "tipp"}}, "not a point"),
    ],
)
def test_bad_declarations_are_refused_with_the_problem_named(perturb, error):
    with pytest.raises(ValueError, match=error):
        gym.make(ARM, perturb=perturb)


@pytest.mark.parametrize("perturb", [0.1, "noise", [("delay", 1)]])
def test_perturb_must_be_a_dict(perturb):
    with pytest.raises(TypeError, match="perturb must be a dict"):
        gym.make(ARM, perturb=perturb)


def test_perturb_is_a_listed_env_option():
    assert "perturb" in envs.plant.ENV_OPTIONS


# ---- pushes --------------------------------------------------------------------------------
def test_a_push_has_its_size_and_duration_and_starts_at_the_declared_rate():
    """Pushes of magnitude F last `periods` steps, and start as a Bernoulli trial per idle
    period with chance c = 1 - exp(-dt / every): a fraction k / (k + (1 - c) / c) of the
    steps is pushed. 64 copies x 150 steps (runs of a few steps, ~2,500 independent
    cycles): 10 % holds the estimate to about four of its standard deviations."""
    every, k, n = 0.25, 3, 64
    vec = _vec(ARM, n, perturb={"push": {"force": 4.0, "every": every, "duration": 0.15}})
    vec.reset(seed=0)
    zero = np.zeros(vec.action_space.shape, np.float32)
    forces = np.array([vec.step(zero)[4]["push"] for _ in range(150)])  # (steps, n, 2)
    size = np.linalg.norm(forces, axis=2)
    pushed = size > 0
    assert np.allclose(size[pushed], 4.0, rtol=1e-12)
    c = -np.expm1(-vec.unwrapped.control_period / every)
    assert abs(pushed.mean() / (k / (k + (1 - c) / c)) - 1) < 0.1
    for copy in range(n):  # every push (a run of one force) lasts k periods
        f = forces[:, copy]
        change = np.flatnonzero(np.any(f[1:] != f[:-1], axis=1)) + 1
        for run in np.split(np.arange(len(f)), change)[1:-1]:  # whole runs only
            assert not pushed[run[0], copy] or len(run) % k == 0


@pytest.mark.parametrize("env_id", [ARM, ACROBOT, "Lagrange/BeadOnRod-v1"])
def test_the_work_of_a_push_is_the_energy_it_adds(env_id):
    """Zero input on a conservative model: over a step the energy changes by the work of
    the held generalised forces, W . (q1 - q0), W from the force in info['push'] at the
    step's start. The integrator's energy error per step at these step sizes is below
    1e-9 J (tests/envs/test_physics.py), so 1e-7 J separates it from a wrong map (the
    pushes' work is ~0.1-1 J per step)."""
    env = gym.make(env_id, perturb={"push": {"force": 6.0, "every": 0.1}}).unwrapped
    _, info = env.reset(seed=1)
    zero = env.input_to_action(np.zeros(env.system.n_u))
    assert np.allclose(env.action_to_input(zero), 0)
    n, worked = env.system.n_q, 0.0
    for _ in range(40):
        x0, e0 = info["state"], info["energy"]
        _, _, term, trunc, info = env.step(zero.astype(np.float32))
        if term or trunc:
            break
        W = env.system.point_forces(x0, next(iter(env.system.points)), info["push"])
        work = W @ (info["state"][:n] - x0[:n])
        assert abs(info["energy"] - e0 - work) < 1e-7
        worked += abs(work)
    assert worked > 0.5  # the pushes did work


def test_a_push_moves_the_unactuated_coordinates():
    """The acrobot's shoulder has no motor: only a push reaches it. From rest at the top,
    a push tips it; without one it stays."""
    system = gym.make(ACROBOT).unwrapped.system
    top = np.array([np.pi, np.pi, 0.0, 0.0])
    Q = system.point_forces(top, "link2", [0.0, 5.0])
    assert abs(Q[0]) > 1.0  # the shoulder's generalised force, N*m
    env = gym.make(ACROBOT, perturb={"push": {"force": 5.0, "every": 0.05}}).unwrapped
    plain = gym.make(ACROBOT).unwrapped
    for e in (env, plain):
        e.reset(seed=0, options={"state": top})
    hold = plain.input_to_action(np.zeros(plain.system.n_u)).astype(np.float32)
    for _ in range(10):
        moved = env.step(hold)[4]["state"]
        still = plain.step(hold)[4]["state"]
    assert abs(moved[0] - np.pi) > 1e-3 and abs(still[0] - np.pi) < 1e-9


def test_a_randomised_copy_is_pushed_like_a_single_env_with_its_values():
    """Per-copy parameters (randomize=) and pushes together: the pushes' generalised
    forces and the integrator read each copy's own parameters."""
    n, row, value = 3, 1, 0.11  # Ibar2 (nominal 1/12) sets none of the task's numbers
    vec = _vec(ARM, n, randomize={}, perturb=ALL)
    single = gym.make(ARM, Ibar2=value, perturb=ALL)
    values = np.full(n, 1 / 12)
    values[row] = value
    obs, _ = vec.reset(seed=4, options={"params": {"Ibar2": values}})
    o1, _ = single.reset(seed=4 + row)
    assert np.array_equal(obs[row], o1)
    pushed = 0
    for a in _actions(single, 30):
        batch = np.zeros((n, 2), np.float32)
        batch[row] = a
        obs, r, *_, info = vec.step(batch)
        o1, r1, *_, i1 = single.step(a)
        assert np.array_equal(obs[row], o1) and r[row] == r1
        assert np.array_equal(info["push"][row], i1["push"])
        pushed += bool(i1["push"].any())
    assert pushed > 0
