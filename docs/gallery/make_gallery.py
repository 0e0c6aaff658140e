"""Render a strip of frames of every Lagrange environment into docs/gallery/<Name>.png.

    SDL_VIDEODRIVER=dummy python docs/gallery/make_gallery.py [--out DIR]

Each strip shows the frames after 0, 15 and 40 steps of a fixed-seed episode under a
simple action (see `action`), so a reader sees the system, its goal and its motion.
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import gymnasium as gym
import matplotlib.image
import numpy as np

import envs
from dynamics.cache import write_atomic

FRAMES = (0, 15, 40)


def action(env_id: str, k: int, env) -> np.ndarray:
    """The action at step k: gentle torques that make each system move."""
    if env_id.endswith("RollingDisk-v1"):
        return np.array([0.0, 0.3 if k < 20 else 0.0])  # steer briefly, then roll free
    if env_id.endswith("BeadOnRod-v1"):  # keep the rod about level; the bead drifts
        r, phi, _, phid = env.unwrapped.state
        return np.array([np.clip(0.5 * r - 2.0 * phi - 0.5 * phid, -1, 1)])
    return np.full(env.action_space.shape, 0.5 * np.sin(0.2 * k))


def strip(env_id: str, seed: int = 0) -> np.ndarray:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=seed)
    frames = []
    for k in range(max(FRAMES) + 1):
        frame = env.render()  # every step, so the disk's track is complete
        if k in FRAMES:
            frames.append(frame)
        _, _, terminated, truncated, _ = env.step(action(env_id, k, env))
        if terminated or truncated:
            raise RuntimeError(f"{env_id}: the gallery episode ended at step {k}.")
    env.close()
    gap = np.full((frames[0].shape[0], 6, 3), 120, dtype=np.uint8)
    return np.concatenate([x for f in frames for x in (f, gap)][:-1], axis=1)


def save_png(path: Path, image: np.ndarray) -> None:
    """Write the PNG atomically (a temporary file and a rename)."""
    buf = io.BytesIO()
    matplotlib.image.imsave(buf, image, format="png")
    write_atomic(path, buf.getvalue())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent, help="directory")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for env_id in envs.ENV_IDS:
        path = args.out / f"{env_id.split('/')[1].split('-')[0]}.png"
        save_png(path, strip(env_id))
        print(path)


if __name__ == "__main__":
    main()
