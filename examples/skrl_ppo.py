"""PPO from skrl (another RL library, PyTorch) on the native vector env: one batched call
steps every copy, as SB3's training here does.

    pip install skrl
    python examples/skrl_ppo.py Lagrange/BeadOnRod-v1 --envs 16 --timesteps 20000

The env is Gymnasium's own `make_vec(..., vectorization_mode="vector_entry_point")`, asked
for same-step autoreset (a finished copy's step returns its reset observation), which is
the transition skrl records; skrl's `wrap_env` recognises a Gymnasium vector env.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
from gymnasium.vector import AutoresetMode

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import envs  # noqa: E402, F401  (registers the Lagrange namespace)


def build(env_id: str, n_envs: int, timesteps: int, out: Path, seed: int = 0):
    """(skrl trainer, wrapped env) for PPO on `n_envs` copies of `env_id`."""
    from skrl.agents.torch.ppo import PPO, PPO_CFG
    from skrl.envs.wrappers.torch import wrap_env
    from skrl.memories.torch import RandomMemory
    from skrl.trainers.torch import SequentialTrainer
    from skrl.utils import set_seed
    from skrl.utils.model_instantiators.torch import deterministic_model, gaussian_model

    set_seed(seed)
    vec = gym.make_vec(
        env_id,
        num_envs=n_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.SAME_STEP,
    )
    env = wrap_env(vec, wrapper="gymnasium")
    spaces = {"observation_space": env.observation_space, "action_space": env.action_space}
    net = [{"name": "net", "input": "OBSERVATIONS", "layers": [64, 64], "activations": "tanh"}]
    models = {
        "policy": gaussian_model(
            **spaces,
            device=env.device,
            clip_actions=True,
            network=net,
            output="ACTIONS",
            initial_log_std=-0.5,
        ),
        "value": deterministic_model(**spaces, device=env.device, network=net, output="ONE"),
    }
    rollouts = 128
    cfg = PPO_CFG(
        rollouts=rollouts,
        learning_epochs=5,
        mini_batches=4,
        discount_factor=0.98,
        learning_rate=3e-4,
    )
    cfg.experiment.directory = str(out)
    cfg.experiment.write_interval = rollouts
    cfg.experiment.checkpoint_interval = timesteps
    memory = RandomMemory(memory_size=rollouts, num_envs=env.num_envs, device=env.device)
    agent = PPO(models=models, memory=memory, **spaces, device=env.device, cfg=cfg)
    trainer_cfg = {"timesteps": timesteps, "headless": True, "disable_progressbar": True}
    trainer = SequentialTrainer(env=env, agents=agent, cfg=trainer_cfg)
    return trainer, env


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env_id")
    parser.add_argument("--envs", type=int, default=16, help="copies in the vector env")
    parser.add_argument("--timesteps", type=int, default=20_000, help="vector steps")
    parser.add_argument("--out", type=Path, default=Path("runs/skrl"))
    args = parser.parse_args(argv)
    trainer, _ = build(args.env_id, args.envs, args.timesteps, args.out)
    trainer.train()
    return 0


if __name__ == "__main__":
    sys.exit(main())
