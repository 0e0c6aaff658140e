"""Gymnasium environments on the derived Lagrangian models.

Importing this package registers, in the `Lagrange` namespace, every id of `ENV_IDS`, each
with its episode limit and a native `vector_entry_point`::

    import gymnasium as gym
    import envs

    env = gym.make("Lagrange/TwoLinkArm-v0")
    vec = gym.make_vec(
        "Lagrange/TwoLinkArm-v0", num_envs=1024, vectorization_mode="vector_entry_point"
    )
"""

from gymnasium.envs.registration import register, registry

_ENVS = {
    # id: (module, env class, max_episode_steps); the vector env is the class "...VectorEnv"
    "Lagrange/TwoLinkArm-v0": ("envs.arm", "TwoLinkArm", 200),
    "Lagrange/Acrobot-v0": ("envs.acrobot", "Acrobot", 500),
    "Lagrange/RollingDisk-v0": ("envs.disk", "RollingDisk", 400),
    "Lagrange/BeadOnRod-v0": ("envs.bead", "BeadOnRod", 200),
    "Lagrange/CrankSlider-v0": ("envs.crank", "CrankSlider", 200),
}

ENV_IDS: tuple[str, ...] = tuple(_ENVS)

for _id, (_module, _name, _steps) in _ENVS.items():
    if _id not in registry:
        register(
            id=_id,
            entry_point=f"{_module}:{_name}Env",
            vector_entry_point=f"{_module}:{_name}VectorEnv",
            max_episode_steps=_steps,
        )

__all__ = ["ENV_IDS"]
