"""Systems beyond the book, each a model, a task and its registration, written as a user
would with the public API only (`dynamics.spec`, `envs`). Importing a module registers its
env, so every command takes it as `examples.<module>:<id>`.

`ENVS` lists every example env by id with the module that registers it (the scripts
`optuna_search.py` and `skrl_ppo.py` register nothing); `specs()` gives them in the
`module:id` form every command takes, and `register_all()` imports them all.
"""

from __future__ import annotations

import importlib

ENVS: dict[str, str] = {
    "Examples/CartPole-v0": "cart_pole",
    "Examples/Furuta-v0": "furuta",
    "Examples/FurutaSwingUp-v0": "furuta_swing_up",
    "Examples/DoubleCartPole-v0": "double_cart_pole",
    "Examples/Kapitza-v0": "kapitza",
    "Examples/ReactionWheel-v0": "reaction_wheel",
    "Examples/Pendubot-v0": "pendubot",
    "Examples/GantryCrane-v0": "gantry_crane",
    "Examples/SeriesElastic-v0": "series_elastic",
    "Examples/PlanarVTOL-v0": "planar_vtol",
    "Examples/Segway-v0": "segway",
    "Examples/ThreeLinkArm-v0": "three_link_arm",
    "Examples/Slew-v0": "slew",
    "Examples/MassChain-v0": "mass_chain",
}
"""Every example env id -> the module of examples/ that registers it on import."""


def specs() -> list[str]:
    """Every example env in the `examples.<module>:<id>` form the commands take."""
    return [f"examples.{module}:{env_id}" for env_id, module in ENVS.items()]


def register_all() -> list[str]:
    """Import every example module (registering its env); returns the ids."""
    for module in dict.fromkeys(ENVS.values()):
        importlib.import_module(f"{__name__}.{module}")
    return list(ENVS)
