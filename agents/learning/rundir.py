"""The run directory: where a training run keeps its files, and the one policy for
a directory that already holds a run.

A run directory holds config.yml (what was trained: env id and version, algorithm,
hyperparameters), checkpoints/ (the newest checkpoint: model, normalisation statistics,
replay buffer), model.zip and vecnormalize.pkl, episodes.csv, eval.csv, evaluations.npz and
learning_curve.png; every file written atomically. Only one process trains into it at a time
(`exclusive`). An earlier run in it is never replaced unasked: it is continued (resumed
from its newest checkpoint; refused when config.yml says it trained something else) or
replaced when asked to; `agents.train` asks with --resume / --overwrite, `agents.check`
resumes a run of the same budget and settings (`run_dir_of` gives each budget a directory
of its own) and replaces it with --fresh.

model.zip, vecnormalize.pkl and the checkpoints are pickles (SB3's format): loading them
runs code, so load only run directories you trust, as with any SB3 model.
"""

from __future__ import annotations

import contextlib
import re
import sys
from pathlib import Path

import yaml

from ..common import UserError, env_slug

try:  # one training process per run directory (POSIX advisory lock)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

CHECKPOINT_PREFIX = "rl_model"
_CHECKPOINT_RE = re.compile(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
# every file a run writes: checkpoints/ holds the CHECKPOINT_FILE ones, the run directory these
CHECKPOINT_FILE = re.compile(rf"{CHECKPOINT_PREFIX}_(?:[a-z_]+_)?\d+_steps\.(?:zip|pkl)")
RUN_FILES = (
    "config.yml",
    "model.zip",
    "vecnormalize.pkl",
    "episodes.csv",
    "eval.csv",
    "evaluations.npz",
    "learning_curve.png",
)
# the temporary name `atomic_path` gives FILE: ".FILE.<8 random characters><FILE's suffix>"
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[a-z0-9_]{8}(?P<suffix>\.[A-Za-z0-9]+)")


def default_run_dir(env_id: str, algo: str, seed: int) -> Path:
    return Path("runs") / "train" / env_slug(env_id) / f"{algo}_seed{seed}"


def run_dir_of(out: Path, env_id: str, algo: str, seed: int, budget: int, tag: str = "") -> Path:
    """`agents.check`'s run directory: each budget trains in a directory of its own, so
    asking for another budget starts a fresh run and keeps the earlier one (asked for
    again, it is resumed or reused); `tag` names a randomised run's setting."""
    return out / "train" / env_slug(env_id) / f"{algo}_seed{seed}_{budget}steps{tag}"


@contextlib.contextmanager
def exclusive(run_dir: Path):
    """Hold `run_dir` for one training process (a lock on run_dir/.lock, released when the
    process ends however it ends); a second process gets a UserError."""
    run_dir.mkdir(parents=True, exist_ok=True)
    if fcntl is None:  # pragma: no cover
        yield
        return
    with open(run_dir / ".lock", "w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise UserError(
                f"Another process is training into {run_dir}; wait for it or choose "
                "another --run-dir."
            ) from None
        yield


def is_stale_temporary(name: str) -> bool:
    """True for the temporary name `atomic_path` gives one of this program's files (a
    process killed while writing leaves it behind; the lock says no writer is alive)."""
    match = _TEMPORARY.fullmatch(name)
    if match is None or not match["name"].endswith(match["suffix"]):
        return False
    return match["name"] in RUN_FILES or CHECKPOINT_FILE.fullmatch(match["name"]) is not None


def remove_stale_temporaries(run_dir: Path) -> list[Path]:
    """Delete what killed writers left in `run_dir`, checkpoints/ and .staging/ (only
    names this program writes); return the deleted paths."""
    stale = [
        path
        for directory in (run_dir, run_dir / "checkpoints")
        if directory.is_dir()
        for path in directory.iterdir()
        if path.is_file() and is_stale_temporary(path.name)
    ]
    stale += [p for p in [run_dir / ".staging" / "evaluations.npz"] if p.exists()]
    for path in stale:
        path.unlink()
    return stale


def _run_files(run_dir: Path) -> list[Path]:
    files = [run_dir / name for name in RUN_FILES if (run_dir / name).exists()]
    ckpt_dir = run_dir / "checkpoints"
    if ckpt_dir.is_dir():
        files += [p for p in ckpt_dir.iterdir() if CHECKPOINT_FILE.fullmatch(p.name)]
    return files


def _holds_a_run(run_dir: Path) -> bool:
    return any(p.name != "config.yml" for p in _run_files(run_dir))


def prepare_run_dir(
    run_dir: Path, env_id: str, algo: str, resume: bool, overwrite: bool, config=None
) -> tuple[int, Path] | None:
    """The checkpoint to resume from, or None for a fresh run (after removing an earlier
    run's files when `overwrite`). An earlier run is never replaced unasked, nor resumed
    with other settings than its `config.yml` records (`config`: the ones asked for now)."""
    if resume and overwrite:
        raise UserError("Give --resume (continue the run) or --overwrite (replace it), not both.")
    found = latest_checkpoint(run_dir / "checkpoints")
    if resume and found is not None:
        _check_same_run(run_dir, env_id, algo)
        if config is not None:
            check_resume_defines(run_dir, config)
        return found
    if _holds_a_run(run_dir) and not overwrite:
        if resume:
            raise UserError(
                f"{run_dir} holds an earlier run but no checkpoint to resume from; pass "
                "--overwrite to replace it, or choose another --run-dir."
            )
        raise UserError(
            f"{run_dir} holds an earlier run; pass --resume to continue it or --overwrite "
            "to replace it, or choose another --run-dir."
        )
    if resume:
        print(f"No checkpoint in {run_dir / 'checkpoints'}; starting a fresh run.", file=sys.stderr)
    for path in _run_files(run_dir):  # a later --resume must not pick up an older run
        path.unlink()
    return None


def check_resume_randomize(run_dir: Path, setting: dict | None) -> None:
    """UserError when `setting` (the hyperparameter `randomize`) differs from the one the run
    in `run_dir` recorded in its config.yml: a resumed run trains on what it began with,
    and its record says so."""
    from ..values import Bad
    from .randomization import check_setting, describe

    config = read_config(Path(run_dir))
    if not config:
        return
    recorded = (config.get("hyperparams") or {}).get("randomize")
    try:
        given, before = check_setting(setting), check_setting(recorded)
    except Bad as exc:
        raise UserError(f"randomize: {exc}.") from None
    if given != before:
        raise UserError(
            f"{run_dir} was trained with {describe(recorded)}, not {describe(given)}; "
            "--resume continues a run with its own settings (leave --randomize out), or "
            "start another run (--run-dir) with the new ones."
        )


DEFINING = ("seed", "n_envs", "hyperparams")
"""What defines a run besides its env and algorithm (`--randomize` and `--params` have checks
of their own); the step count may grow: resuming to a larger --timesteps continues a run."""


def check_resume_defines(run_dir: Path, config: dict) -> None:
    """UserError naming each setting of `config` that defines the run (`DEFINING`, the
    hyperparameters one by one, whichever file gave them) and differs from the run's
    config.yml: a resumed run goes on with what it began with, and its record says so."""
    then, now = _defining(read_config(run_dir)), _defining(config)
    differ = [
        f"{k}: {then.get(k)!r} in the run, {now.get(k)!r} given"
        for k in sorted((set(then) | set(now)) - {"hyperparams[randomize]"})  # its own check
        if then.get(k) != now.get(k)
    ]
    if differ:
        raise UserError(
            f"{run_dir} holds a run begun with other settings ({'; '.join(differ)}); --resume "
            "continues a run with its own (give the run's --seed, --n-envs and --hyperparams), "
            "or start another run (--run-dir) with the new ones."
        )


def _defining(config: dict) -> dict:
    """`config`'s DEFINING settings as config.yml stores them, the hyperparameters one by one."""
    flat = yaml.safe_load(yaml.safe_dump({k: config.get(k) for k in DEFINING}))
    flat.update((f"hyperparams[{k}]", v) for k, v in (flat.pop("hyperparams") or {}).items())
    return flat


def _check_same_run(run_dir: Path, env_id: str, algo: str) -> None:
    earlier = read_config(run_dir)
    if earlier and (earlier["env_id"], earlier["algo"]) != (env_id, algo):
        raise UserError(
            f"{run_dir} holds a {earlier['algo']} run on {earlier['env_id']}, "
            f"not {algo} on {env_id}; resume it with those, or choose another --run-dir."
        )


def latest_checkpoint(directory: Path) -> tuple[int, Path] | None:
    """(timesteps, model path) of the newest checkpoint in `directory`, if any."""
    found = []
    for path in directory.glob(f"{CHECKPOINT_PREFIX}_*_steps.zip"):
        match = _CHECKPOINT_RE.search(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return max(found) if found else None


def companion(directory: Path, kind: str, steps: int) -> Path:
    return directory / f"{CHECKPOINT_PREFIX}_{kind}_{steps}_steps.pkl"


def check_earlier_run(run_dir: Path, budget: int, hp: dict) -> None:
    """UserError when `run_dir` holds a run trained with another budget or hyperparameters
    than asked for now (--fresh retrains it)."""
    if not (run_dir / "config.yml").exists() or not (run_dir / "checkpoints").is_dir():
        return
    earlier = read_config(run_dir)
    now = yaml.safe_load(yaml.safe_dump(hp))  # as config.yml stores it
    then = earlier.get("hyperparams") or {}
    differ = [
        f"{k}: {then.get(k)!r} in the run, {now.get(k)!r} now"
        for k in sorted(set(now) | set(then))
        if then.get(k) != now.get(k)
    ]
    if earlier.get("n_timesteps") != budget:
        differ.insert(0, f"budget: {earlier.get('n_timesteps')} in the run, {budget} now")
    if differ:
        raise UserError(
            f"{run_dir} holds a run trained with other settings than asked for now "
            f"({'; '.join(differ)}). Pass --fresh to retrain it, or --out DIR to keep it."
        )


def finished_run(run_dir: Path, expected: dict, trained: int) -> bool:
    """Whether `run_dir` holds a time-budget run that ended where a fresh run of the same
    seed on the same machine ends again, and trained what `expected` says (each entry: env_id,
    algo, seed, hyperparams, budget_s, n_timesteps, task fingerprint; equal to its
    config.yml): solved (solved.json, the confirmed model kept as model.zip; the stop is on
    the step schedule), or through its step cap (`trained`, the steps it trained, reaching
    n_timesteps), where the clock did not decide. `agents.check` reuses such a run; one
    that ran out of time trains afresh (a clock cannot be resumed)."""
    if not all((run_dir / name).is_file() for name in ("config.yml", "model.zip")):
        return False
    then = read_config(run_dir)
    now = yaml.safe_load(yaml.safe_dump(expected))  # as config.yml stores it
    if any(then.get(key) != value for key, value in now.items()):
        return False
    return (run_dir / "solved.json").is_file() or trained >= int(then.get("n_timesteps", 0))


# ---- a saved run, read back ----------------------------------------------------------------
def read_config(run_dir: Path) -> dict:
    """A run's config.yml ({} when there is none), checked: a mapping whose env_id and algo
    are strings; UserError of one line otherwise."""
    from .hparams import ALGOS, read_yaml

    path = run_dir / "config.yml"
    if not path.exists():
        return {}
    config = read_yaml(path)
    if not isinstance(config, dict):
        raise UserError(f"{path} is not a run's config (expected a mapping of env_id, algo, ...).")
    for key in ("env_id", "algo"):
        if not isinstance(config.get(key), str):
            raise UserError(f"{path}: {key} must be a string, got {config.get(key)!r:.60}.")
    if config["algo"] not in ALGOS:
        known = ", ".join(ALGOS)
        raise UserError(f"{path}: algo must be one of {known}, got {config['algo']!r:.60}.")
    if not isinstance(config.get("hyperparams") or {}, dict):
        raise UserError(f"{path}: hyperparams must be a mapping.")
    return config


def check_run_is_for(run_dir: Path, config: dict, env_id: str | None) -> None:
    """UserError when the run in `run_dir` (its `config`) was trained on another env id or
    version than `env_id`, which it would otherwise act in without a word whenever the
    spaces happen to have the same shapes."""
    trained = config.get("env_id")
    if env_id is None or trained is None:
        return
    from ..common import check_env_id

    try:
        trained_id = check_env_id(trained)
    except UserError:
        trained_id = trained
    if trained_id != env_id:
        raise UserError(
            f"{run_dir} holds a model trained on {trained}, not on {env_id}; evaluate it on "
            f"{trained} (or train one for {env_id})."
        )
