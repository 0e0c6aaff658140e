"""The checks every example env passes, shared by the example test files."""

import warnings

import gymnasium as gym
from gymnasium.utils.env_checker import check_env


def assert_both_checkers_pass(env_id: str) -> None:
    """Gymnasium's env checker (with rendering) and stable-baselines3's, warnings as
    errors."""
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(env_id, render_mode="rgb_array").unwrapped, skip_render_check=False)
        sb3_check_env(gym.make(env_id).unwrapped)
