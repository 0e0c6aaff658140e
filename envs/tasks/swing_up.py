"""The PPO settings of a swing-up task that hands over to LQR, as a task's `hyperparams`.

Measured on the acrobot and kept by the pendubot and the Furuta swing-up examples: a long
horizon (gamma), exploration (entropy, a wide initial std) that keeps the agent swinging
until it reaches LQR's set, rollouts of 512 steps per copy that hold a whole episode, and
the hand-over (`agents.control.handover`: LQR acts inside the level set dx' P dx = level).
A task may also declare its copies (`n_envs`; the acrobot's 16).
"""

from __future__ import annotations


def swing_up_ppo(n_timesteps: int, gamma: float, handover: dict, n_envs: int | None = None) -> dict:
    """A task's `hyperparams["ppo"]` for a swing-up handed over to LQR by `handover`
    ({"level": L, "verify": seconds, optionally "shaping": W}); `n_envs` copies where
    given, else the YAML default's."""
    copies = {} if n_envs is None else {"n_envs": n_envs}
    return {
        **copies,
        "n_timesteps": n_timesteps,
        "n_steps": 512,
        "gamma": gamma,
        "learning_rate": "lin_3.0e-4",
        "ent_coef": 0.01,
        "normalize": {"norm_obs": True, "norm_reward": True, "gamma": gamma},
        "policy_kwargs": {"net_arch": [64, 64], "log_std_init": 0.5},
        "handover": handover,
    }
