"""Speed and accuracy of the Lagrange environments against Gymnasium's Acrobot-v1.

    OMP_NUM_THREADS=1 python -m benchmarks.env_speed [--quick] [--per-copy] [--perturb] [--sizes N]

Measured in one run, so the ratios hold on a shared machine even when absolute figures
move: `gymnasium.make` time per id (warm model cache; numba's import, paid once per process,
is reported apart), single-env steps/s through `gymnasium.make` with its default wrappers
(actions drawn beforehand, never `Box.sample`), env-steps/s of the native vector env
(`make_vec(..., vectorization_mode="vector_entry_point")`) at N = 64, 1024, 16384 against a
`SyncVectorEnv` of Acrobot-v1 copies (and, when they are installed, EnvPool's and gymnax's
Acrobot-v1 on this CPU, float32 and float64; none is a dependency of the project), with
derivative evaluations per second (an env step's evaluations: Acrobot-v1's one RK4 step
makes 4, ours substeps x stages of the env's integrator), and the relative energy error of
one unforced episode. The key contenders are measured in alternating rounds (medians; the
ratio to SyncVectorEnv is taken within each round), so a shared machine's load cancels.
Acrobot-v1's energy is measured with this project's `two_link_arm` model at its
parameters (m = 1, l = 1, lc = 0.5, I = 1 about the mass centre, g = 9.8; its second
angle is relative, ours absolute), from the same large swing as ours.
"""

from __future__ import annotations

import argparse
import importlib
import time

import gymnasium as gym
import numpy as np

import dynamics
import envs
from dynamics.methods import METHODS
from envs.contract import available_cores

SIZES = (64, 1024, 16384)
SWING = np.array([1.5, 1.5, 0.0, 0.0])  # a large swing (absolute angles), released at rest


def steps_per_second(env, actions: np.ndarray, seconds: float) -> float:
    """Steps/s of env.step over pre-drawn actions, resetting when an episode ends."""
    env.reset(seed=0)
    n, k, start = len(actions), 0, time.perf_counter()
    while True:
        for _ in range(200):
            _, _, term, trunc, _ = env.step(actions[k % n])
            k += 1
            if term or trunc:
                env.reset()
        elapsed = time.perf_counter() - start
        if elapsed > seconds:
            return k / elapsed


def vector_steps_per_second(vec, seconds: float, min_steps: int = 3) -> float:
    """Env-steps/s of a vector env (num_envs copies per step) over pre-drawn actions."""
    rng = np.random.default_rng(0)
    actions = (
        [vec.action_space.sample() for _ in range(4)]
        if not hasattr(vec.single_action_space, "shape") or vec.single_action_space.shape == ()
        else [rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32) for _ in range(4)]
    )
    vec.reset(seed=0)
    vec.step(actions[0])  # first call: numba loads its cached kernels
    k, start = 0, time.perf_counter()
    while True:
        vec.step(actions[k % 4])
        k += 1
        elapsed = time.perf_counter() - start
        if elapsed > seconds and k >= min_steps:
            return k * vec.num_envs / elapsed


def unforced_drift(env_id: str, state=None, episodes: int = 20) -> float:
    """Largest relative energy error over unforced episodes from the env's own starting
    distribution (or from `state`), relative to the scale of tests/envs/test_physics.py."""
    vec = gym.make_vec(env_id, num_envs=episodes, vectorization_mode="vector_entry_point")
    options = None if state is None else {"state": state}
    _, info = vec.reset(seed=0, options=options)
    e0 = info["energy"]
    scale = energy_scale(env_id, vec.unwrapped.system, e0)
    alive, worst = np.ones(episodes, dtype=bool), 0.0
    zero = np.zeros(vec.action_space.shape)
    for _ in range(vec.unwrapped.max_episode_steps):
        _, _, term, trunc, info = vec.step(zero)
        worst = max(worst, (np.abs(info["energy"] - e0) / scale)[alive].max(initial=0.0))
        alive &= ~(term | trunc)
        if not alive.any():
            break
    return worst


def energy_scale(env_id: str, system, e0: np.ndarray):
    p = system.parameters
    if "Arm" in env_id or "Acrobot" in env_id:  # potential range, inverted minus hanging
        return 2 * (p["m1"] * p["g"] * p["l1"] + p["m2"] * p["g"] * (p["l"] + p["l2"]))
    if "Bead" in env_id:
        return p["m"] * p["g"] * p["rod_length"] / 2
    if "Crank" in env_id:
        return p["M"] * p["g"] * abs(p["s"])
    return np.abs(e0)  # the disk: its own energy


def acrobot_v1_drift(steps: int = 500) -> float:
    """Relative energy error of Acrobot-v1 over an unforced episode from SWING."""
    arm = dynamics.get_model("two_link_arm").compile(
        m1=1.0, m2=1.0, l=1.0, l1=0.5, l2=0.5, Ibar1=1.0, Ibar2=1.0, g=9.8
    )
    env = gym.make("Acrobot-v1", max_episode_steps=steps).unwrapped
    env.reset(seed=0)
    env.state = np.array([SWING[0], SWING[1] - SWING[0], 0.0, 0.0])

    def energy(s):  # Acrobot-v1 state (theta1, theta2 relative, rates) -> absolute angles
        return float(arm.energy([s[0], s[0] + s[1], s[2], s[2] + s[3]]))

    e0, worst = energy(env.state), 0.0
    for _ in range(steps):
        env.step(1)  # action 1: zero torque
        worst = max(worst, abs(energy(env.state) - e0))
    scale = 2 * (1.0 * 9.8 * 0.5 + 1.0 * 9.8 * 1.5)
    return worst / scale


def evaluations(env) -> int:
    """Derivative evaluations per env step."""
    return env.substeps * METHODS[env.integrator].stages


def envpool_vector(n: int):
    """EnvPool's Acrobot-v1 x n on the cores available, as a stepping function, or None."""
    try:
        import envpool
    except ImportError:
        return None
    pool = envpool.make(
        "Acrobot-v1", env_type="gymnasium", num_envs=n, num_threads=min(n, available_cores())
    )
    pool.reset()
    actions = [np.random.default_rng(i).integers(0, 3, n).astype(np.int32) for i in range(4)]
    return lambda k: pool.step(actions[k % 4])


def gymnax_rollout(n: int, x64: bool):
    """gymnax's Acrobot-v1 x n (jit + vmap + scan over 50 steps, random actions) as a
    stepping function that takes 50 steps per call, or None."""
    try:
        import gymnax
        import jax
    except ImportError:
        return None
    jax.config.update("jax_enable_x64", x64)
    env, params = gymnax.make("Acrobot-v1")

    def run(key, state):
        def body(state, k):
            a = jax.random.randint(k, (n,), 0, 3)
            keys = jax.random.split(k, n)
            out = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, a, params)
            return out[1], out[2]

        return jax.lax.scan(body, state, jax.random.split(key, 50))

    key = jax.random.PRNGKey(0)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, n), params)
    fn = jax.jit(run)
    fn(key, state)[1].block_until_ready()

    def step(k):
        jax.config.update("jax_enable_x64", x64)  # the other precision may have run last
        fn(jax.random.PRNGKey(k), state)[1].block_until_ready()

    return step


def rate(step, per_call: int, seconds: float, min_calls: int = 3) -> float:
    """Env-steps/s of a stepping function that advances `per_call` env-steps per call."""
    step(0)
    k, start = 0, time.perf_counter()
    while True:
        step(k)
        k += 1
        elapsed = time.perf_counter() - start
        if elapsed > seconds and k >= min_calls:
            return k * per_call / elapsed


def vector_table(sizes, seconds: float, rounds: int = 3) -> None:
    """Env-steps/s (ratio to SyncVectorEnv of Acrobot-v1) and derivative evaluations/s at
    each N: the key contenders in alternating rounds, then every Lagrange env once."""
    arm_id = "Lagrange/TwoLinkArm-v1"
    arm_evals = evaluations(gym.make(arm_id).unwrapped)
    cores = available_cores()
    names = [
        ("Acrobot-v1 SyncVectorEnv", 4),
        (f"EnvPool Acrobot-v1 ({cores} threads)", 4),
        ("gymnax Acrobot-v1 CPU float32", 4),
        ("gymnax Acrobot-v1 CPU float64", 4),
        (f"{arm_id} native ({cores} threads)", arm_evals),
        (f"{arm_id} native (1 thread)", arm_evals),
    ]
    cells: dict[str, list[str]] = {name: [] for name, _ in names}
    for n in sizes:
        sync = gym.vector.SyncVectorEnv([lambda: gym.make("Acrobot-v1")] * n)
        native = {
            t: gym.make_vec(arm_id, n, vectorization_mode="vector_entry_point", num_threads=t)
            for t in (cores, 1)
        }
        steppers = [
            (vector_stepper(sync), n),
            (envpool_vector(n), n),
            (gymnax_rollout(n, x64=False), 50 * n),
            (gymnax_rollout(n, x64=True), 50 * n),
            (vector_stepper(native[cores]), n),
            (vector_stepper(native[1]), n),
        ]
        runs = [[] for _ in steppers]
        for _ in range(rounds):
            for i, (step, per_call) in enumerate(steppers):
                if step is not None:
                    runs[i].append(rate(step, per_call, seconds / rounds))
        base = np.array(runs[0])
        for (name, evals), r in zip(names, runs):
            if not r:
                cells[name].append("not installed")
                continue
            v, ratio = np.median(r), np.median(np.array(r) / base)
            cells[name].append(f"{v:,.0f} ({ratio:.1f}x) {v * evals:.1e}/s")
        sync.close()
    print("\n| env-steps/s (vs SyncVectorEnv, same rounds) and derivative evaluations/s "
          "| evaluations per step | " + " | ".join(f"N = {n}" for n in sizes) + " |")  # fmt: skip
    print("|---|---|" + "---|" * len(sizes))
    for name, evals in names:
        print(f"| {name} | {evals} | " + " | ".join(cells[name]) + " |")
    print("\n| env (native vector env, default threads) | evaluations per step | "
          + " | ".join(f"N = {n}" for n in sizes) + " |")  # fmt: skip
    print("|---|---|" + "---|" * len(sizes))
    for env_id in envs.ENV_IDS:
        row = []
        for n in sizes:
            vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
            v = vector_steps_per_second(vec, seconds / rounds)
            row.append(f"{v:,.0f} {v * evaluations(vec.unwrapped):.1e}/s")
        print(f"| {env_id} | {evaluations(gym.make(env_id).unwrapped)} | " + " | ".join(row) + " |")


def per_copy_table(sizes, seconds: float, rounds: int = 5) -> None:
    """The cost of per-copy model parameters (`randomize=`) against parameters shared by
    every copy, and of redrawing them mid-episode (every 10 steps of each copy, `when=10`)
    against drawing them at resets only: env-steps/s of TwoLinkArm-v1 (one thread), the
    single env through `gymnasium.make` and the native vector env at each N, in
    alternating rounds (the ratios taken within each round, medians)."""
    arm_id = "Lagrange/TwoLinkArm-v1"
    inertial = {"Ibar1": (0.75 / 12, 1.25 / 12), "Ibar2": (0.75 / 12, 1.25 / 12)}
    every = {k: {"dist": "uniform", "low": lo, "high": hi, "when": 10}
             for k, (lo, hi) in inertial.items()}  # fmt: skip
    kinds = (("shared", {}), ("per-copy", {"randomize": inertial}),
             ("every 10", {"randomize": every}))  # fmt: skip
    print("\n| TwoLinkArm-v1, one thread | shared parameters (env-steps/s) "
          "| per-copy parameters | per-copy / shared (same rounds) "
          "| redrawn every 10 steps | every 10 / per-copy |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    _alternating_rounds(arm_id, dict(kinds), sizes, seconds, rounds, _per_copy_row)


def _per_copy_row(label: str, runs: dict) -> None:
    shared, per_copy = np.array(runs["shared"]), np.array(runs["per-copy"])
    every = np.array(runs["every 10"])
    print(f"| {label} | {np.median(shared):,.0f} | {np.median(per_copy):,.0f} "
          f"| {np.median(per_copy / shared):.3f} | {np.median(every):,.0f} "
          f"| {np.median(every / per_copy):.3f} |")  # fmt: skip


PERTURBATIONS = {
    "noise": {"obs_noise": 0.01, "action_noise": 0.1},
    "motor and delay": {"motor_k": 0.5, "delay": 1},
    "pushes": {"push": {"force": 5.0}},
    "all": {"obs_noise": 0.01, "action_noise": 0.1, "motor_k": 0.5, "delay": 1,
            "push": {"force": 5.0}},
}  # fmt: skip


def perturb_table(sizes, seconds: float, rounds: int = 5) -> None:
    """The cost of perturbations (`perturb=`) against none: env-steps/s of TwoLinkArm-v1
    (one thread), the single env through `gymnasium.make` and the native vector env at
    each N, in alternating rounds (the ratio to no perturbation taken within each round,
    medians)."""
    arm_id = "Lagrange/TwoLinkArm-v1"
    kinds = {"off": None, **PERTURBATIONS}
    print("\n| TwoLinkArm-v1, one thread | off (env-steps/s) | "
          + " | ".join(f"{k} (ratio to off)" for k in PERTURBATIONS) + " |")  # fmt: skip
    print("|---|---|" + "---|" * len(PERTURBATIONS))
    options = {k: {"perturb": v} for k, v in kinds.items()}
    _alternating_rounds(arm_id, options, sizes, seconds, rounds, _ratio_row)


def _alternating_rounds(env_id, kinds: dict, sizes, seconds: float, rounds: int, row) -> None:
    """Env-steps/s of `env_id` made with each kind's options (name -> env options; one
    thread), the single env through `gymnasium.make` and the native vector env at each N,
    the kinds taking turns in every round; `row(label, {kind: [rate per round]})` prints."""
    actions = np.random.default_rng(0).uniform(-1, 1, (1000, 2)).astype(np.float32)
    single = {k: gym.make(env_id, **opts) for k, opts in kinds.items()}
    runs = {k: [] for k in kinds}
    for _ in range(rounds):
        for k, env in single.items():
            runs[k].append(steps_per_second(env, actions, seconds / rounds))
    row("single env (gymnasium.make)", runs)
    for n in sizes:
        steppers = {
            k: vector_stepper(gym.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                                           num_threads=1, **opts))
            for k, opts in kinds.items()
        }  # fmt: skip
        runs = {k: [] for k in kinds}
        for _ in range(rounds):
            for k, step in steppers.items():
                runs[k].append(rate(step, n, seconds / rounds))
        row(f"native vector env, N = {n}", runs)


def _ratio_row(label: str, runs: dict) -> None:
    off = np.array(runs["off"])
    ratios = [f"{np.median(np.array(v) / off):.2f}" for k, v in runs.items() if k != "off"]
    print(f"| {label} | {np.median(off):,.0f} | " + " | ".join(ratios) + " |")


def vector_stepper(vec):
    """A vector env as a stepping function over pre-drawn actions (reset once)."""
    rng = np.random.default_rng(0)
    if vec.single_action_space.shape == ():
        actions = [vec.action_space.sample() for _ in range(4)]
    else:
        actions = [rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32) for _ in range(4)]
    vec.reset(seed=0)
    return lambda k: vec.step(actions[k % 4])


def make_time(env_id: str) -> float:
    start = time.perf_counter()
    gym.make(env_id)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter timings (noisier)")
    parser.add_argument("--sizes", type=int, nargs="*", default=list(SIZES))
    parser.add_argument(
        "--per-copy", action="store_true",
        help="only the cost of per-copy parameters (randomize=) against shared ones",
    )  # fmt: skip
    parser.add_argument(
        "--perturb", action="store_true",
        help="only the cost of perturbations (perturb=) against none",
    )  # fmt: skip
    args = parser.parse_args(argv)
    seconds = 0.5 if args.quick else 2.0
    if args.perturb:
        perturb_table(args.sizes, 2 * seconds)
        return
    if args.per_copy:
        per_copy_table(args.sizes, 2 * seconds)
        return

    start = time.perf_counter()
    importlib.import_module("envs")  # numba and the runtime kernels: once per process

    print(f"import of envs (numba): {time.perf_counter() - start:.2f} s")
    for env_id in envs.ENV_IDS:  # warm the model cache and numba's kernel cache
        env = gym.make(env_id)
        env.reset(seed=0)
        env.step(env.action_space.sample())
    rng = np.random.default_rng(0)
    ids = ("Acrobot-v1",) + envs.ENV_IDS
    made = {env_id: make_time(env_id) for env_id in ids}
    runs = {}
    for env_id in ids:
        env = gym.make(env_id)
        if env_id == "Acrobot-v1":
            actions = rng.integers(0, 3, 1000)
        else:
            actions = rng.uniform(-1, 1, (1000,) + env.action_space.shape).astype(np.float32)
        runs[env_id] = (env, actions)
    # rounds that alternate between the envs, each against Acrobot-v1 in the same round,
    # so that a shared machine's changing load cancels from the ratios (medians shown)
    sps = {env_id: [] for env_id in ids}
    for _ in range(5):
        for env_id in ids:
            sps[env_id].append(steps_per_second(*runs[env_id], seconds / 5))
    base = np.array(sps["Acrobot-v1"])
    print("\n| env | make (s) | steps/s, single env | vs Acrobot-v1 (same rounds) |")
    print("|---|---|---|---|")
    for env_id in ids:
        ratio = np.median(np.array(sps[env_id]) / base)
        print(f"| {env_id} | {made[env_id]:.3f} | {np.median(sps[env_id]):,.0f} | {ratio:.2f}x |")

    vector_table(args.sizes, seconds)
    print("\n| env | control period (s) | integrator x substeps | evaluations per step "
          "| relative energy error, unforced episode |")  # fmt: skip
    print("|---|---|---|---|---|")
    print(f"| Acrobot-v1 (large swing, 100 s) | 0.2 | rk4 x1 | 4 | {acrobot_v1_drift():.1e} |")
    arm = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    swing = unforced_drift("Lagrange/TwoLinkArm-v1", state=SWING, episodes=1)
    print(f"| Lagrange/TwoLinkArm-v1 (same swing, 10 s) | 0.05 | {arm.integrator} x "
          f"{arm.substeps} | {evaluations(arm)} | {swing:.1e} |")  # fmt: skip
    for env_id in envs.ENV_IDS:
        u = gym.make(env_id).unwrapped
        drift = unforced_drift(env_id)
        print(f"| {env_id} (own starts) | {u.control_period} | {u.integrator} x {u.substeps} "
              f"| {evaluations(u)} | {drift:.1e} |")  # fmt: skip


if __name__ == "__main__":
    main()
