"""Training hyperparameters: the algorithm's defaults, then what the env's task declares,
then the packaged YAML's entry for the env id (if any), then a user's file; each value
checked (type, range, size) where it is read, and turned into SB3's keyword arguments.

One YAML file per algorithm (agents/hyperparams/<algo>.yml), RL Zoo style: a `default`
entry for every env, and entries keyed by env id that override it (also for envs that are
not Lagrange envs, such as Pendulum-v1). Keys the training program interprets itself:
`n_timesteps` (default budget), `n_envs`, `policy`, `normalize` (bool or VecNormalize
keyword arguments), `action_noise` ({type: normal, sigma: S}), `policy_kwargs` (with
`activation_fn` by name), `handover` (agents.handover) and schedules written "lin_X"
(linear decay from X to 0). Everything else goes to the algorithm.

A bad value is a UserError of one line naming the file (or the task) and the key. YAML
aliases are expanded only up to `MAX_VALUES` values (a few kilobytes of nested aliases
would otherwise expand to gigabytes), and messages show values shortened.
"""

from __future__ import annotations

import difflib
import inspect
import math
import reprlib
from pathlib import Path

import numpy as np
import yaml

from .common import UserError, task_of

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
)
_short = reprlib.Repr()
_short.maxlevel, _short.maxstring, _short.maxother = 2, 40, 40
_short.maxlist = _short.maxdict = _short.maxtuple = 4


def algorithms() -> dict:
    """The algorithms by name: the one table (SB3's classes, imported on first use)."""
    from stable_baselines3 import PPO, SAC, TD3

    return {"ppo": PPO, "sac": SAC, "td3": TD3}


ALGOS = ("ppo", "sac", "td3")
"""The names of `algorithms()` (without importing SB3)."""


def short(value) -> str:
    """`value`'s repr, cut to a few dozen characters (cheap on shared, aliased structures)."""
    return _short.repr(value)


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


def _table(path: Path) -> dict:
    table = read_yaml(path) or {}
    if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
        raise UserError(f"{path} must map env ids (or 'default') to dicts of hyperparameters.")
    return table


# ---- checking values ---------------------------------------------------------------------
class _Bad(Exception):
    """What a value should have been (the caller adds the file and the key)."""


def _int(lo: int, hi: int):
    def check(v):
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise _Bad(f"an integer in [{lo}, {hi}]")
        return v

    return check


def _real(lo: float, hi: float, open_low: bool = False):
    def check(v):
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or not (lo < v if open_low else lo <= v) or v > hi:
            raise _Bad(f"a number in {'(' if open_low else '['}{lo}, {hi}]")
        return float(v)

    return check


def _schedule(number):
    """A number, or "lin_X" (a linear decay from X) with X such a number."""

    def check(v):
        if isinstance(v, str) and v.startswith("lin_"):
            try:
                number(float(v[4:]))
            except (ValueError, _Bad) as exc:
                raise _Bad(f"'lin_X' with X {exc}") from None
            return v
        try:
            return number(v)
        except _Bad as exc:
            raise _Bad(f"{exc} or 'lin_X'") from None

    return check


def _bool(v):
    if not isinstance(v, bool):
        raise _Bad("true or false")
    return v


def _optional(check):
    def optional(v):
        return None if v is None else check(v)

    return optional


def _either(*checks):
    def check(v):
        wants = []
        for c in checks:
            try:
                return c(v)
            except _Bad as exc:
                wants.append(str(exc))
        raise _Bad(" or ".join(wants))

    return check


def _choice(*names):
    def check(v):
        if v not in names:
            raise _Bad(f"one of {', '.join(map(repr, names))}")
        return v

    return check


def _layers(v):
    if not isinstance(v, list) or not 1 <= len(v) <= 16:
        raise _Bad("a list of 1 to 16 layer widths")
    return [_int(1, 4096)(n) for n in v]


def _net_arch(v):
    if isinstance(v, dict):
        if not v or set(v) - {"pi", "vf", "qf"}:
            raise _Bad("a list of layer widths, or a table of them under pi, vf or qf")
        return {k: _layers(w) for k, w in v.items()}
    return _layers(v)


ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")
_POLICY_KWARGS = {
    "net_arch": _net_arch,
    "activation_fn": _choice(*ACTIVATIONS),
    "log_std_init": _real(-20.0, 5.0),
    "ortho_init": _bool,
    "full_std": _bool,
    "use_expln": _bool,
    "squash_output": _bool,
    "share_features_extractor": _bool,
    "n_critics": _int(1, 16),
}
_NORMALIZE = {
    "norm_obs": _bool,
    "norm_reward": _bool,
    "clip_obs": _real(0.0, 1e6, open_low=True),
    "clip_reward": _real(0.0, 1e6, open_low=True),
    "gamma": _real(0.0, 1.0, open_low=True),
    "epsilon": _real(0.0, 1.0, open_low=True),
}


def _table_of(rules: dict):
    def check(v):
        if not isinstance(v, dict) or set(v) - set(rules):
            raise _Bad(f"a table of {', '.join(rules)}")
        out = {}
        for k, value in v.items():
            try:
                out[k] = rules[k](value)
            except _Bad as exc:
                raise _Bad(f"{k} to be {exc}") from None
        return out

    return check


def _noise(v):
    if not isinstance(v, dict) or v.get("type") != "normal" or set(v) != {"type", "sigma"}:
        raise _Bad("{type: normal, sigma: S}")
    return {"type": "normal", "sigma": _real(0.0, 10.0, open_low=True)(v["sigma"])}


def _handover(v):
    from .handover import check_handover

    try:
        return check_handover(v)
    except ValueError as exc:
        raise _Bad(str(exc)) from None


_fraction = _real(0.0, 1.0)
RULES = {
    "n_timesteps": _int(1, 10**10),
    "n_envs": _int(1, 1024),
    "policy": _choice("MlpPolicy"),
    "normalize": _either(_bool, _table_of(_NORMALIZE)),
    "action_noise": _optional(_noise),
    "policy_kwargs": _optional(_table_of(_POLICY_KWARGS)),
    "handover": _optional(_handover),
    "gamma": _real(0.0, 1.0, open_low=True),
    "gae_lambda": _fraction,
    "learning_rate": _schedule(_real(0.0, 1.0, open_low=True)),
    "clip_range": _schedule(_real(0.0, 10.0, open_low=True)),
    "clip_range_vf": _optional(_schedule(_real(0.0, 1e6, open_low=True))),
    "n_steps": _int(1, 10**6),
    "batch_size": _int(1, 10**6),
    "n_epochs": _int(1, 1000),
    "ent_coef": _either(_real(0.0, 10.0), _choice("auto")),
    "vf_coef": _real(0.0, 100.0),
    "max_grad_norm": _real(0.0, 1e6, open_low=True),
    "use_sde": _bool,
    "sde_sample_freq": _int(-1, 10**6),
    "normalize_advantage": _bool,
    "target_kl": _optional(_real(0.0, 100.0, open_low=True)),
    "stats_window_size": _int(1, 10**6),
    "buffer_size": _int(1, 10**8),
    "learning_starts": _int(0, 10**9),
    "tau": _real(0.0, 1.0, open_low=True),
    "train_freq": _int(1, 10**6),
    "gradient_steps": _int(-1, 10**6),
    "policy_delay": _int(1, 1000),
    "target_policy_noise": _real(0.0, 10.0),
    "target_noise_clip": _real(0.0, 10.0),
    "target_update_interval": _int(1, 10**6),
    "optimize_memory_usage": _bool,
}


def _scalar(v):
    if v is not None and not isinstance(v, (bool, int, float, str)):
        raise _Bad("a number, a string, true/false or null (no rule knows this key)")
    if isinstance(v, str) and len(v) > 200:
        raise _Bad("a string of at most 200 characters")
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
        except _Bad as exc:
            raise UserError(f"{where}: {key} must be {exc}, got {short(value)}.") from None
    return out


# ---- the layers ----------------------------------------------------------------------------
def check_algo_name(algo: str) -> str:
    if algo not in ALGOS:
        close = difflib.get_close_matches(str(algo), ALGOS, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise UserError(f"Unknown algorithm {algo!r}.{hint} Known: {', '.join(ALGOS)}.")
    return algo


def load(algo: str, env_id: str, path: str | Path | None = None) -> dict:
    """The hyperparameters of `algo` for `env_id` (a fresh dict): the YAML's `default`,
    updated by the task's `hyperparams[algo]`, the YAML's entry for env_id and, if `path`
    is given, that file's `default` and env_id entries. Every value is checked."""
    check_algo_name(algo)
    packaged_path = DIRECTORY / f"{algo}.yml"
    packaged = _table(packaged_path)
    hp = check_entries(packaged.get("default", {}), f"{packaged_path} (default)")
    try:
        task = task_of(env_id)
    except UserError:
        if env_id not in packaged and path is None:
            raise UserError(
                f"No {algo} hyperparameters for {env_id!r}: it is not a Lagrange env and "
                f"{algo}.yml has no entry for it; give --hyperparams FILE."
            ) from None
    else:
        hp.update(check_entries(task.hyperparams.get(algo, {}), f"{env_id}'s task ({algo})"))
    hp.update(check_entries(packaged.get(env_id, {}), f"{packaged_path} ({env_id})"))
    if path is not None:
        user = _table(Path(path))
        for entry in ("default", env_id):
            hp.update(check_entries(user.get(entry, {}), f"{path} ({entry})"))
    return hp


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
        kwargs["activation_fn"] = table[_choice(*ACTIVATIONS)(kwargs["activation_fn"])]
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
