"""Training hyperparameters: the algorithm's defaults, then what the env's task implies
(agents.learning.defaults: discount, reward scale, shaping), then what the env's task declares,
then the packaged YAML's entry for the env id (if any), then a user's file; each value
checked (type, range, size) where it is read, and turned into SB3's keyword arguments.

One YAML file per algorithm (agents/learning/hyperparams/<algo>.yml), RL Zoo style: a `default`
entry for every env, and entries keyed by env id that override it (also for envs that are
not Lagrange envs, such as Pendulum-v1). Keys the training program interprets itself:
`n_timesteps` (default budget), `n_envs`, `policy`, `normalize` (bool or VecNormalize
keyword arguments, and `center`: agents.learning.uncentered), `reward_scale` and `shaping`
({lqr: W}, agents.learning.shaping), `action_noise` ({type: normal, sigma: S}),
`policy_kwargs` (with `activation_fn` by name), `handover` (agents.control.handover),
`randomize` (physical parameters drawn at every reset of the training envs:
agents.learning.randomization) and schedules
written "lin_X" (linear decay from X to 0). Everything else goes to the algorithm.

A bad value is a UserError of one line naming the file (or the task) and the key. YAML
aliases are expanded only up to `MAX_VALUES` values (a few kilobytes of nested aliases
would otherwise expand to gigabytes), and messages show values shortened.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import yaml

from dynamics.checks import ALGORITHMS, unknown

from ..common import UserError, check_file_applies, task_of
from ..values import (
    Bad,
    choice,
    either,
    integer,
    optional,
    real,
    schedule_of,
    short,
    true_or_false,
)

DIRECTORY = Path(__file__).parent / "hyperparams"
MAX_FILE_BYTES = 1 << 20
MAX_VALUES = 10_000
"""The most values (after expanding aliases) a hyperparameter file may hold."""
MANAGED_KEYS = (
    "n_timesteps",
    "n_envs",
    "policy",
    "normalize",
    "action_noise",
    "policy_kwargs",
    "handover",
    "randomize",
    "reward_scale",
    "shaping",
    "feedforward",
)


def algorithms() -> dict:
    """The algorithms by name: the one table (SB3's and sb3-contrib's classes, imported on
    first use)."""
    from sb3_contrib import TQC, CrossQ
    from stable_baselines3 import PPO, SAC, TD3

    # in the order of ALGOS (tested)
    return {"ppo": PPO, "sac": SAC, "td3": TD3, "tqc": TQC, "crossq": CrossQ}


def off_policy(algo: str) -> bool:
    """Whether learner `algo` learns from a replay buffer (SAC, TD3, TQC, CrossQ)."""
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    return issubclass(algorithms()[algo], OffPolicyAlgorithm)


ALGOS = ALGORITHMS
"""The names of `algorithms()` (dynamics.checks.ALGORITHMS, without importing SB3)."""


# ---- reading files -----------------------------------------------------------------------
def read_yaml(path: Path):
    """The YAML document at `path`, refusing large files and alias bombs cheaply."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise UserError(f"Cannot read {path}: {exc.strerror}.") from None
    if len(data) > MAX_FILE_BYTES:
        raise UserError(f"{path} is larger than {MAX_FILE_BYTES} bytes.")
    try:
        node = yaml.compose(data, Loader=yaml.SafeLoader)
        if node is None:
            return None
        if _expanded_size(node) > MAX_VALUES:
            raise UserError(
                f"{path} expands to more than {MAX_VALUES} values (through aliases); write "
                "the hyperparameters out."
            )
        return yaml.SafeLoader("").construct_document(node)
    except yaml.YAMLError as exc:
        raise UserError(f"{path} is not valid YAML: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise UserError(f"{path} nests too deeply.") from None


def _expanded_size(root) -> int:
    """How many values the node graph `root` stands for once aliases are expanded (capped
    just above MAX_VALUES; an alias shares its node, so this memoises on identity)."""
    sizes: dict[int, int] = {}

    def size(node) -> int:
        if id(node) in sizes:
            return sizes[id(node)]
        sizes[id(node)] = MAX_VALUES + 1  # a recursive alias counts as too many
        if isinstance(node, yaml.MappingNode):
            total = 1 + sum(size(k) + size(v) for k, v in node.value)
        elif isinstance(node, yaml.SequenceNode):
            total = 1 + sum(size(v) for v in node.value)
        else:
            total = 1
        sizes[id(node)] = min(total, MAX_VALUES + 1)
        return sizes[id(node)]

    return size(root)


def read_table(path: Path) -> dict:
    """The hyperparameter file at `path`: env ids (or `default`) to dicts, checked in shape."""
    table = read_yaml(path) or {}
    if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
        raise UserError(f"{path} must map env ids (or 'default') to dicts of hyperparameters.")
    return table


def _layers(v):
    if not isinstance(v, list) or not 1 <= len(v) <= 16:
        raise Bad("a list of 1 to 16 layer widths")
    return [integer(1, 4096)(n) for n in v]


def _net_arch(v):
    if isinstance(v, dict):
        if not v or set(v) - {"pi", "vf", "qf"}:
            raise Bad("a list of layer widths, or a table of them under pi, vf or qf")
        return {k: _layers(w) for k, w in v.items()}
    return _layers(v)


ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")
_POLICY_KWARGS = {
    "net_arch": _net_arch,
    "activation_fn": choice(*ACTIVATIONS),
    "log_std_init": real(-20.0, 5.0),
    "ortho_init": true_or_false,
    "full_std": true_or_false,
    "use_expln": true_or_false,
    "squash_output": true_or_false,
    "share_features_extractor": true_or_false,
    "n_critics": integer(1, 16),
    "n_quantiles": integer(1, 1000),
}
_NORMALIZE = {
    "center": true_or_false,  # ours: subtract the running mean (SB3's way) or not
    "norm_obs": true_or_false,
    "norm_reward": true_or_false,
    "clip_obs": real(0.0, 1e6, open_low=True),
    "clip_reward": real(0.0, 1e6, open_low=True),
    "gamma": real(0.0, 1.0, open_low=True),
    "epsilon": real(0.0, 1.0, open_low=True),
}


def _table_of(rules: dict):
    def check(v):
        if not isinstance(v, dict) or set(v) - set(rules):
            raise Bad(f"a table of {', '.join(rules)}")
        out = {}
        for k, value in v.items():
            try:
                out[k] = rules[k](value)
            except Bad as exc:
                raise Bad(f"{k} to be {exc}") from None
        return out

    return check


def _noise(v):
    if not isinstance(v, dict) or v.get("type") != "normal" or set(v) != {"type", "sigma"}:
        raise Bad("{type: normal, sigma: S}")
    return {"type": "normal", "sigma": real(0.0, 10.0, open_low=True)(v["sigma"])}


def _handover(v):
    from ..control.handover import check_handover

    try:
        check_handover(v)
    except ValueError as exc:
        raise Bad(str(exc)) from None
    return v  # as written (config.yml records it so; agents.control.handover fills the defaults)


def _shaping(v):
    form = Bad(
        "{lqr: W, success: B} (W in [0, 100]: the LQR potential's weight; B in [0, 100]: "
        "the bonus per step inside the success set; 0 turns either off, an absent key is 0)"
    )
    if not isinstance(v, dict) or not v or not set(v) <= {"lqr", "success"}:
        raise form
    try:
        return {k: real(0.0, 100.0)(v[k]) for k in ("lqr", "success") if k in v}
    except Bad:
        raise form from None


def _randomize(v):
    from .randomization import check_setting

    return check_setting(v)


_fraction = real(0.0, 1.0)
RULES = {
    "n_timesteps": integer(1, 10**10),
    "n_envs": integer(1, 1024),
    "policy": choice("MlpPolicy"),
    "normalize": either(true_or_false, _table_of(_NORMALIZE)),
    "action_noise": optional(_noise),
    "policy_kwargs": optional(_table_of(_POLICY_KWARGS)),
    "handover": optional(_handover),
    "randomize": optional(_randomize),
    "reward_scale": real(0.0, 1e6, open_low=True),
    "shaping": optional(_shaping),
    "feedforward": true_or_false,
    "gamma": real(0.0, 1.0, open_low=True),
    "gae_lambda": _fraction,
    "learning_rate": schedule_of(real(0.0, 1.0, open_low=True)),
    "clip_range": schedule_of(real(0.0, 10.0, open_low=True)),
    "clip_range_vf": optional(schedule_of(real(0.0, 1e6, open_low=True))),
    "n_steps": integer(1, 10**6),
    "batch_size": integer(1, 10**6),
    "n_epochs": integer(1, 1000),
    "ent_coef": either(real(0.0, 10.0), choice("auto")),
    "vf_coef": real(0.0, 100.0),
    "max_grad_norm": real(0.0, 1e6, open_low=True),
    "use_sde": true_or_false,
    "sde_sample_freq": integer(-1, 10**6),
    "normalize_advantage": true_or_false,
    "target_kl": optional(real(0.0, 100.0, open_low=True)),
    "stats_window_size": integer(1, 10**6),
    "buffer_size": integer(1, 10**8),
    "learning_starts": integer(0, 10**9),
    "tau": real(0.0, 1.0, open_low=True),
    "train_freq": integer(1, 10**6),
    "gradient_steps": integer(-1, 10**6),
    "policy_delay": integer(1, 1000),
    "target_policy_noise": real(0.0, 10.0),
    "target_noise_clip": real(0.0, 10.0),
    "target_update_interval": integer(1, 10**6),
    "optimize_memory_usage": true_or_false,
}


def _scalar(v):
    if v is not None and not isinstance(v, (bool, int, float, str)):
        raise Bad("a number, a string, true/false or null (no rule knows this key)")
    if isinstance(v, str) and len(v) > 200:
        raise Bad("a string of at most 200 characters")
    return v


def check_entries(entries: dict, where: str) -> dict:
    """`entries` with each value checked against `RULES` (a key without a rule may hold a
    scalar; the algorithm's constructor checks the key); UserError naming `where` and the
    key for the first bad one."""
    out = {}
    for key, value in entries.items():
        if not isinstance(key, str):
            raise UserError(f"{where}: keys must be names, got {short(key)}.")
        try:
            out[key] = RULES.get(key, _scalar)(value)
        except Bad as exc:
            raise UserError(f"{where}: {key} must be {exc}, got {short(value)}.") from None
    return out


# ---- the layers ----------------------------------------------------------------------------
def check_algo_name(algo: str) -> str:
    if algo not in ALGOS:
        raise UserError(str(unknown("algorithm", algo, ALGOS)))
    return algo


def load(algo: str, env_id: str, path: str | Path | None = None) -> dict:
    """The hyperparameters of `algo` for `env_id` (a fresh dict): the YAML's `default`,
    updated by the task's `hyperparams[algo]`, the YAML's entry for env_id and, if `path`
    is given, that file's `default` and env_id entries. Every value is checked."""
    check_algo_name(algo)
    packaged_path = DIRECTORY / f"{algo}.yml"
    packaged = read_table(packaged_path)
    hp = check_entries(packaged.get("default", {}), f"{packaged_path} (default)")
    try:
        task = task_of(env_id)
    except UserError:
        if env_id not in packaged and path is None:
            raise UserError(
                f"No {algo} hyperparameters for {env_id!r}: it is not a Lagrange env and "
                f"{algo}.yml has no entry for it; give --hyperparams FILE."
            ) from None
        task, own = None, {}
    else:
        own = task.hyperparams.get(algo, {})
        hp.update(check_entries(derived_for(env_id, task, own), f"{env_id}'s declaration"))
    layers = [(own, f"{env_id}'s task ({algo})")]
    layers.append((packaged.get(env_id, {}), f"{packaged_path} ({env_id})"))
    if path is not None:
        user = read_table(Path(path))
        check_file_applies(user, path, env_id)
        layers += [(user.get(entry, {}), f"{path} ({entry})") for entry in ("default", env_id)]
    declared = any("n_envs" in table for table, _ in layers)
    if task is not None and not off_policy(algo) and not declared:
        from .defaults import rollout

        hp.update(rollout(task, hp))  # a declared n_envs stands
    for table, where in layers:
        hp.update(check_entries(table, where))
    return hp


def derived_for(env_id: str, task, own: dict) -> dict:
    """agents.learning.defaults.derived, without the LQR shaping where the task declares settings of
    its own for the algorithm (they were measured without it; the built-in tasks' budgets)
    or hands over to LQR (its hand-over carries its own energy shaping, agents.control.handover)."""
    from .defaults import derived

    out = derived(env_id, task)
    if own:
        out.pop("shaping", None)
    return out


def check_algo(env_id: str) -> str:
    """The algorithm the main job trains on `env_id`: the task's `algo` ('ppo' otherwise)."""
    try:
        return check_algo_name(task_of(env_id).algo)
    except UserError:
        return "ppo"


# ---- hyperparameters -> SB3 keyword arguments ------------------------------------------
def schedule(value):
    """'lin_3e-4' -> a linear decay from 3e-4 to 0 over the run (picklable, resumable)."""
    from stable_baselines3.common.utils import LinearSchedule

    if isinstance(value, str) and value.startswith("lin_"):
        return LinearSchedule(float(value[4:]), 0.0, 1.0)
    return value


def policy_kwargs(raw: dict | None) -> dict:
    import torch.nn as nn

    kwargs = dict(raw or {})
    if "activation_fn" in kwargs:
        table = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
        kwargs["activation_fn"] = table[choice(*ACTIVATIONS)(kwargs["activation_fn"])]
    return kwargs


def algo_kwargs(algo: str, hp: dict, action_dim: int, source: str | None = None) -> dict:
    """Keyword arguments for the algorithm's constructor from checked hyperparameters
    (`source` names the file in error messages; default <algo>.yml)."""
    from stable_baselines3.common.noise import NormalActionNoise

    cls = algorithms()[check_algo_name(algo)]
    kwargs = {k: schedule(v) for k, v in hp.items() if k not in MANAGED_KEYS}
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "policy", "env"}
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        where = source or f"{algo}.yml"
        raise UserError(f"Unknown {algo} hyperparameter(s) {unknown} in {where}.")
    kwargs["policy_kwargs"] = policy_kwargs(hp.get("policy_kwargs"))
    noise = hp.get("action_noise")
    if noise is not None:
        sigma = _noise(noise)["sigma"]
        kwargs["action_noise"] = NormalActionNoise(
            np.zeros(action_dim), sigma * np.ones(action_dim)
        )
    return kwargs


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> dict:
    """The checked hyperparameters for (algo, env_id), packaged and `path`'s; also checked
    against the algorithm's constructor. Every problem a one-line UserError."""
    check_algo_name(algo)
    if path is not None and not Path(path).is_file():
        raise UserError(f"Hyperparameter file {path} does not exist.")
    hp = load(algo, env_id, path)
    algo_kwargs(algo, hp, 1, source=None if path is None else str(path))
    return hp
