"""Training with randomised physical parameters: the `randomize` hyperparameter and the
`--randomize` option of `agents.train`, `agents.check` and `agents.evaluate`.

A setting is a table {key: value} (YAML, or `--randomize KEY=VALUE` on the command line,
repeatable), resolved against the env's nominal parameters into the env option
`randomize={name: (low, high)}` (absolute values drawn uniformly at every reset of each
copy, `envs.plant`):

- `inertial: F`: every inertial parameter over [1 - F, 1 + F] x its nominal value, each
  body the model declares (`ModelSpec.bodies`) as a whole: its moments and products of
  inertia scaled by one draw (drawn apart, a thin disk's or a bicycle frame's would often
  be no body's);
- `NAME: F` (a number): that parameter over [1 - F, 1 + F] x its nominal value;
- `NAME: [LOW, HIGH]` (`NAME=LOW:HIGH` on the command line): absolute values, in the
  model's units (`python -m dynamics show MODEL` lists them).

"Inertial" means the parameters in kg or kg*m^2: masses, moments and products of inertia.
Lengths, including the positions of mass centres, are left out: their unit (m) does not tell
a mass centre from the geometry a task's goals and limits are built on (a link's length, a
wheel's radius). A named entry overrides what `inertial` set for that parameter.
"""

from __future__ import annotations

import math

from dynamics.checks import UnknownParameterError, parameter_name

from ..common import UserError, spec
from ..values import Bad, short

INERTIAL_UNITS = ("kg", "kg*m^2")
"""The units of the parameters `inertial` randomises."""
GROUP = "inertial"


def inertial_parameters(system) -> list[str]:
    """The names of `system`'s inertial parameters (unit kg or kg*m^2), in model order."""
    return [name for name, unit in system.units.items() if unit in INERTIAL_UNITS]


def _fraction(v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 1:
        raise Bad("a fraction F in [0, 1) (the range [1 - F, 1 + F] x nominal)")
    return float(v)


def _pair(v) -> list[float]:
    ok = isinstance(v, (list, tuple)) and len(v) == 2
    ok = ok and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v
    )
    if not ok or not v[0] <= v[1]:
        raise Bad("[LOW, HIGH], finite numbers with LOW <= HIGH, in the model's units")
    return [float(x) for x in v]


def check_setting(value) -> dict | None:
    """The hyperparameter `randomize` checked for its form (the names are checked against
    the env's model when it is resolved); raises `Bad`."""
    if value is None:
        return None
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise Bad(f"a table {{{GROUP}: F, NAME: F or [LOW, HIGH]}}")
    out = {}
    for key, v in value.items():
        try:
            out[key] = (
                _fraction(v) if key == GROUP or not isinstance(v, (list, tuple)) else _pair(v)
            )
        except Bad as exc:
            raise Bad(f"{key} to be {exc}") from None
    return out


def parse_option(items: list[str] | None) -> dict | None:
    """`--randomize` values (KEY=F or NAME=LOW:HIGH, each given once) -> a setting; None when
    none is given. UserError for a malformed one."""
    if not items:
        return None
    setting: dict = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        try:
            if not sep or not key:
                raise ValueError
            if ":" in text:
                lo, hi = text.split(":")
                value = [float(lo), float(hi)]
            else:
                value = float(text)
        except ValueError:
            raise UserError(
                f"--randomize {item!r}: expected {GROUP}=F, NAME=F or NAME=LOW:HIGH (e.g. "
                f"{GROUP}=0.25 for every inertial parameter over [0.75, 1.25] x nominal)."
            ) from None
        if key in setting:
            raise UserError(f"--randomize names {key!r} twice.")
        setting[key] = value
    try:
        return check_setting(setting)
    except Bad as exc:
        raise UserError(f"--randomize: {exc}.") from None


def ranges(system, setting: dict | None) -> dict | None:
    """The env option `randomize=` for `setting` on `system` (its nominal parameters): {name:
    (low, high)}, absolute, except the moments of each body the model declares
    (`ModelSpec.bodies`), which `inertial` scales as a whole: the first one drawn as a scale
    over [1 - F, 1 + F] and the others `Same` as it, so that every copy's body is one some
    mass distribution has. None for no setting. UserError naming an unknown parameter or a
    model without inertial parameters."""
    if setting is None:
        return None
    try:
        setting = check_setting(setting)
    except Bad as exc:
        raise UserError(f"randomize: {exc}, got {short(setting)}.") from None
    nominal = system.parameters
    out: dict[str, tuple[float, float]] = {}
    if GROUP in setting:
        names = inertial_parameters(system)
        if not names:
            raise UserError(f"randomize: {system.name} has no inertial parameters (kg, kg*m^2).")
        out.update({name: scaled(nominal[name], setting[GROUP]) for name in names})
        out.update(_whole_bodies(system, names, setting))
    for key, value in setting.items():
        if key == GROUP:
            continue
        try:
            parameter_name(key, nominal, system.name, "randomize")
        except UnknownParameterError as exc:
            raise UserError(f"{exc} (Or {GROUP!r} for every mass and inertia.)") from None
        out[key] = tuple(value) if isinstance(value, list) else scaled(nominal[key], value)
    return out


def _whole_bodies(system, names: list[str], setting: dict) -> dict:
    """The entries that draw each declared body's inertial moments (of `names`, not named in
    `setting` on their own) with one scale, in the declared dict form (YAML-safe)."""
    out = {}
    f = setting[GROUP]
    for reads in system.bodies.values():
        members = [k for k in names if k in reads and k not in setting]
        if len(members) < 2:
            continue
        first = members[0]
        out[first] = {"dist": "uniform", "low": 1 - f, "high": 1 + f, "apply": "scale"}
        out.update({k: {"dist": "same", "parameter": first} for k in members[1:]})
    return out


def recorded(randomize: dict) -> dict:
    """The env option `randomize=` as the run's config.yml keeps it: (low, high) as lists,
    the declared dict forms as they are."""
    return {k: dict(v) if isinstance(v, dict) else list(v) for k, v in randomize.items()}


def scaled(nominal: float, fraction: float) -> tuple[float, float]:
    """[1 - fraction, 1 + fraction] x nominal as (low, high) (ordered for a negative nominal,
    such as a product of inertia)."""
    a, b = (1 - fraction) * nominal, (1 + fraction) * nominal
    return (min(a, b), max(a, b))


def env_kwargs(env_id: str, setting: dict | None) -> dict:
    """Keyword arguments for gym.make / make_vec: {'randomize': ranges} or {}; UserError
    when the env refuses them (an impossible range)."""
    if setting is None:
        return {}
    import gymnasium as gym

    from ..common import lagrange_env

    env = gym.make(spec(env_id))
    try:
        out = ranges(lagrange_env(env).system, setting)
    finally:
        env.close()
    try:  # the env checks the ranges (a positive parameter's low > 0, the model's conditions)
        gym.make(spec(env_id), randomize=out).close()
    except ValueError as exc:
        raise UserError(f"randomize on {env_id}: {exc}") from None
    return {"randomize": out}


def add_option(parser, where: str, extra: str = "") -> None:
    """The `--randomize KEY=VALUE` option (repeatable) of a program's `parser`."""
    parser.add_argument(
        "--randomize",
        action="append",
        metavar="KEY=VALUE",
        help=f"draw physical parameters at every reset of {where} (repeatable): "
        f"{GROUP}=F (every mass and inertia over [1-F, 1+F] x nominal), NAME=F, or "
        f"NAME=LOW:HIGH (absolute, model units){extra}",
    )


def tag(setting: dict | None) -> str:
    """A suffix naming `setting` in a run directory's name ('' for none), e.g.
    '_randomized-inertial0.25'."""
    if not setting:
        return ""
    parts = [
        f"{k}{v[0]:g}-{v[1]:g}" if isinstance(v, list) else f"{k}{v:g}" for k, v in setting.items()
    ]
    return "_randomized-" + "+".join(parts)


def describe(setting: dict | None) -> str:
    """One phrase for reports: 'nominal parameters' or what is randomised."""
    if not setting:
        return "nominal parameters"
    parts = []
    for key, v in setting.items():
        what = "every mass and inertia" if key == GROUP else key
        if isinstance(v, list):
            parts.append(f"{what} in [{v[0]:g}, {v[1]:g}]")
        else:
            parts.append(f"{what} over [{1 - v:g}, {1 + v:g}] x nominal")
    return "randomised: " + "; ".join(parts)
