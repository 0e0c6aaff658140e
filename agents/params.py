"""Model parameters from a file: the `--params FILE.yml` option of the agents' commands.

    python -m agents.identify Lagrange/TwoLinkArm-v1 --data arm.npz --out runs/identify/arm
    python -m agents.lqr Lagrange/TwoLinkArm-v1 --params runs/identify/arm/parameters.yml

The file names model parameters with their values, either as `agents.identify` writes it
(`parameters:` holding every parameter; its `env_id` and `friction` entries are not model
parameters: friction estimates are reported, not applied) or as a plain mapping
(`m2: 1.4`). Every env the command makes then has these parameters, as
`gym.make(env_id, **parameters)` would give it: within `applied`, the agents make their
envs from `agents.common.spec(env_id)`, a copy of the registration with the values (the
registry itself is never written), so the agents designed, trained and scored by the
command all see the same plant. A trained run records them (its
config.yml's `env_options`, and its task fingerprint changes with them, so a run trained
on other parameters is never resumed or reused as this one); `agents.check` trains and
reports in directories named with their hash (`tag`).

Refused in one line, before any work: a missing or unreadable file, a file that is not
YAML of names and numbers, a file identified on another env (its `env_id`), a name the
env's model does not declare (with the closest name), a value that is not a finite number.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import warnings
from pathlib import Path

from dynamics.checks import UnknownParameterError, parameter_name

from .common import UserError, applied, current, task_of


def add_option(parser) -> None:
    """The `--params FILE.yml` option (agents.params)."""
    parser.add_argument(
        "--params",
        metavar="FILE.yml",
        type=Path,
        help="model parameters by name (the parameters.yml that agents.identify writes, or "
        "a mapping such as 'm2: 1.4'): every env the command makes has them, as "
        "gym.make(ENV_ID, **parameters) would; unknown names are refused",
    )


def model_parameters(env_id: str) -> list[str]:
    """The names of the parameters of `env_id`'s model (a Lagrange env id)."""
    from envs.resolved import compile_system

    return list(compile_system(task_of(env_id).model, {}).parameters)


def load(path: str | Path, env_id: str) -> dict[str, float]:
    """The parameters `path` names, checked against `env_id`'s model; UserError (one line)
    for a missing, unreadable or malformed file, an unknown name or a non-finite value."""
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"--params: no file {path}.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"--params: cannot read {path}: {exc}.") from None
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" (line {where.line + 1})" if where is not None else ""
        raise UserError(f"--params: {path} is not valid YAML{at}.") from None
    if isinstance(data, dict) and isinstance(data.get("parameters"), dict):
        stored = data.get("env_id")
        if stored is not None and str(stored) != env_id:
            raise UserError(
                f"--params: {path} was identified on {stored}, not {env_id}; give the file "
                "identified on this env (its model's parameters differ)."
            )
        if data.get("friction"):
            warnings.warn(
                f"{path}: the friction estimates are not parameters of the model and are "
                "not applied.",
                stacklevel=2,
            )
        data = data["parameters"]
    if not isinstance(data, dict) or not data:
        raise UserError(
            f"--params: {path} should map parameter names to numbers (as 'm2: 1.4', or "
            f"agents.identify's parameters.yml), got {type(data).__name__}."
        )
    known = model_parameters(env_id)
    values = {}
    for name, value in data.items():
        try:
            parameter_name(name, known, f"{env_id}'s model", f"--params: {path}")
        except UnknownParameterError as exc:
            raise UserError(str(exc)) from None
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        try:
            number = float(value) if ok else math.nan
        except OverflowError:  # an integer of hundreds of digits
            number = math.inf
        if not math.isfinite(number):
            raise UserError(
                f"--params: {path}: {name} must be a finite number, got {_shown(value)}."
            )
        values[str(name)] = number
    return _held_by_model(path, env_id, values)


def _held_by_model(path, env_id: str, values: dict[str, float]) -> dict[str, float]:
    """`values`, once the model takes them (signs, ranges, conditions, bodies); UserError
    in the model's words otherwise, before any work."""
    from envs.resolved import compile_system

    try:
        compile_system(task_of(env_id).model, values)
    except ValueError as exc:
        raise UserError(f"--params: {path}: {exc}") from None
    return values


def tag(env_ids) -> str:
    """A suffix for run and report directories: '_params-HASH' of the values applied to
    `env_ids` (one id or several), '' when none."""
    ids = [env_ids] if isinstance(env_ids, str) else list(env_ids)
    values = {e: sorted(current(e).items()) for e in ids if current(e)}
    if not values:
        return ""
    return "_params-" + hashlib.sha256(repr(sorted(values.items())).encode()).hexdigest()[:8]


def record(env_id: str, env_options: dict) -> dict:
    """A run's config.yml entry of what its envs were made with: the randomisation's
    ranges (agents.learning.randomization) and the applied parameters ({} when neither)."""
    from .learning.randomization import recorded

    options = {}
    if env_options:  # what the setting meant for this env: absolute ranges, model units
        options["randomize"] = recorded(env_options["randomize"])
    if current(env_id):
        options["parameters"] = current(env_id)
    return {"env_options": options} if options else {}


def check_resume(run_dir: str | Path, env_id: str) -> None:
    """UserError when the run in `run_dir` recorded other parameters than those applied
    now: a resumed run trains on what it began with, and its record says so."""
    from .learning.rundir import read_config

    config = read_config(Path(run_dir))
    if not config:
        return
    then = (config.get("env_options") or {}).get("parameters") or {}
    if then != current(env_id):
        said = lambda v: ", ".join(f"{k}={x:g}" for k, x in v.items()) or "none"  # noqa: E731
        raise UserError(
            f"{run_dir} was trained with the parameters {said(then)}, not {said(current(env_id))}"
            " (--params); --resume continues a run with its own, or start another run "
            "(--run-dir) with the new ones."
        )


def load_for(path: str | Path | None, env_ids) -> dict[str, dict[str, float]]:
    """{env id: its parameters from `path`} for each of `env_ids` ({} when no file)."""
    if path is None:
        return {}
    return {e: load(path, e) for e in env_ids}


@contextlib.contextmanager
def applied_all(values: dict[str, dict[str, float]]):
    """`applied` for each env id of `values` (load_for's result)."""
    with contextlib.ExitStack() as stack:
        for env_id, these in values.items():
            stack.enter_context(applied(env_id, these))
        yield


def _shown(value) -> str:
    digits = len(str(abs(value))) if isinstance(value, int) else 0
    return f"an integer of {digits} digits" if digits > 20 else f"{value!r:.60}"
