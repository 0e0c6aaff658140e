"""Training environments for stable-baselines3: a native Gymnasium vector env seen through
SB3's `VecEnv` interface, or SB3's own `DummyVecEnv` of single environments.

Gymnasium's vector envs and SB3's VecEnv differ in two ways this adapter bridges: SB3 wants
a list of per-env info dicts with the last observation of a finished episode under
"terminal_observation" and the first observation of the next one returned in its place
(Gymnasium's "same-step" autoreset), and SB3 seeds through `seed()` before `reset()`.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecMonitor, VecNormalize

from ..common import current, spec
from ..control.handover import HandOverVecEnv, handover_options

VECTORIZATIONS = ("auto", "native", "dummy")


class GymnasiumVecEnv(VecEnv):
    """SB3 `VecEnv` over a Gymnasium `VectorEnv` that autoresets in the same step."""

    def __init__(self, venv: gym.vector.VectorEnv):
        mode = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                f"GymnasiumVecEnv needs a vector env with autoreset_mode=SAME_STEP "
                f"(it returns the next episode's first observation with the last one in "
                f"info['final_obs']); {venv!r} uses {mode}."
            )
        self.venv = venv
        self.render_mode = getattr(venv, "render_mode", None)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self):
        seeds = self._seeds
        seed = None if seeds[0] is None else [int(s) for s in seeds]
        obs, info = self.venv.reset(seed=seed)
        self.reset_infos = self._split_infos(info)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape((self.num_envs, *self.action_space.shape))

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = np.logical_or(terminated, truncated)
        infos = self._split_infos(info)
        for i in np.flatnonzero(dones):
            final = info["final_info"]
            infos[i] = _row(final, i)
            infos[i]["terminal_observation"] = info["final_obs"][i]
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, rewards.astype(np.float32), dones, infos

    def _split_infos(self, info: dict) -> list[dict[str, Any]]:
        """Gymnasium's dict of arrays (with '_key' masks) -> SB3's list of dicts."""
        out: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for key, value in info.items():
            if key.startswith("_") or key in ("final_obs", "final_info"):
                continue
            mask = info.get(f"_{key}")
            if mask is None or mask.all():  # every row: split at once (the common case)
                for row, v in zip(out, _rows(value, self.num_envs)):
                    row[key] = v
                continue
            for i in np.flatnonzero(mask):
                out[i][key] = _row(value, i)
        return out

    def close(self) -> None:
        self.venv.close()

    def get_images(self):
        return [self.venv.render()]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        result = getattr(self.venv, method_name)(*args, **kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


def _rows(value, n: int) -> list:
    """[_row(value, i) for i in range(n)], the same objects, split by numpy at once."""
    if isinstance(value, dict):
        parts = {k: _rows(v, n) for k, v in value.items() if not k.startswith("_")}
        return [{k: v[i] for k, v in parts.items()} for i in range(n)]
    return list(value) if isinstance(value, np.ndarray) else [value[i] for i in range(n)]


def _row(value, i: int):
    """Row i of a batched info value (dicts of arrays recursively, without '_' masks)."""
    if isinstance(value, dict):
        return {k: _row(v, i) for k, v in value.items() if not k.startswith("_")}
    return value[i]


def native_vector_env(env_id: str, n_envs: int, **kwargs) -> gym.vector.VectorEnv:
    """The registry's native batched env (vector_entry_point), asked for same-step
    autoreset; an env whose constructor does not take `autoreset_mode` is made as it is
    (and `supports_native` then reports whether SB3 can drive it). kwargs: env options."""
    mode = "vector_entry_point"
    try:
        return gym.make_vec(
            spec(env_id),
            num_envs=n_envs,
            vectorization_mode=mode,
            autoreset_mode=AutoresetMode.SAME_STEP,
            **kwargs,
        )
    except (TypeError, ValueError):  # the constructor rejects the keyword
        return gym.make_vec(spec(env_id), num_envs=n_envs, vectorization_mode=mode, **kwargs)


def supports_native(env_id: str) -> bool:
    """True if `env_id` has a vector_entry_point whose env autoresets in the same step."""
    registered = gym.spec(env_id)
    if registered.vector_entry_point is None:
        return False
    venv = native_vector_env(env_id, 1)
    try:
        return venv.metadata.get("autoreset_mode") == AutoresetMode.SAME_STEP
    finally:
        venv.close()


def make_sb3_vec_env(
    env_id: str, n_envs: int, seed: int, vectorization: str = "auto", env_kwargs=None
) -> VecEnv:
    """n_envs copies of `env_id` for SB3, with episode statistics (VecMonitor / Monitor).

    vectorization: "native" (Gymnasium vector_entry_point, one batched numpy call per step),
    "dummy" (SB3's DummyVecEnv of single envs) or "auto" (native when available).
    env_kwargs: env options (such as `randomize`) for every copy."""
    env_kwargs = dict(env_kwargs or {})
    if vectorization not in VECTORIZATIONS:
        raise ValueError(f"vectorization must be one of {VECTORIZATIONS}, got {vectorization!r}.")
    native = vectorization == "native" or (vectorization == "auto" and supports_native(env_id))
    if native:
        venv = VecMonitor(GymnasiumVecEnv(native_vector_env(env_id, n_envs, **env_kwargs)))
    else:
        venv = make_vec_env(
            env_id,
            n_envs,
            vec_env_cls=DummyVecEnv,
            env_kwargs={**current(env_id), **(env_kwargs or {})},
        )
    venv.seed(seed)
    return venv


# ---- the training run's envs -------------------------------------------------------------
def _normalize_kwargs(hp: dict) -> dict | None:
    """VecNormalize's keyword arguments from `normalize` (None: no VecNormalize), with
    `center` (default False: observations scaled about zero, agents.learning.uncentered)."""
    normalize = hp.get("normalize", False)
    if not normalize:
        return None
    return {"center": False, **(normalize if isinstance(normalize, dict) else {})}


def task_reward(venv: VecEnv, env_id: str, hp: dict) -> VecEnv:
    """`venv` with the reward scale, LQR shaping and success bonus the hyperparameters ask
    for (agents.learning.shaping; the registered reward is untouched), or `venv` itself.
    (Whether the task's reward is flat inside its success set is said where it matters, in
    the diagnosis of an agent that misses the set: agents.scoring.diagnosis, from the probe
    of agents.learning.flat.)"""
    from ..common import task_of
    from .defaults import episode_steps
    from .shaping import TaskRewardVecEnv, lqr_potential

    scale = float(hp.get("reward_scale", 1.0))
    weight = float((hp.get("shaping") or {}).get("lqr", 0.0))
    bonus = float((hp.get("shaping") or {}).get("success", 0.0))
    if scale == 1.0 and not weight and not bonus:
        return venv
    gamma = float(hp.get("gamma", 0.99))
    potential = None
    if weight:
        horizon = episode_steps(env_id, task_of(env_id))
        potential = lqr_potential(env_id, weight, gamma, horizon)
    return TaskRewardVecEnv(venv, scale, potential, gamma, bonus)


def make_envs(env_id: str, hp: dict, n_envs: int, seed: int, vectorization: str, eval_envs: int):
    """Training and evaluation VecEnvs, both wrapped in VecNormalize if the YAML asks (its
    observations scaled about zero unless `center: true`). With
    the hyperparameter `randomize` (agents.learning.randomization) both draw their physical
    parameters at every reset: the evaluations during training score the distribution the
    agent is trained on."""
    from .randomization import env_kwargs

    kwargs = env_kwargs(env_id, hp.get("randomize"))
    train_env = make_sb3_vec_env(env_id, n_envs, seed, vectorization, kwargs)
    eval_env = make_sb3_vec_env(env_id, eval_envs, seed + 10_000, vectorization, kwargs)
    handover = handover_options(hp.get("handover"))
    if handover is not None:  # the agent learns in the closed loop it will act in
        gamma = float(hp.get("gamma", 0.99))
        # the agent learns to aim at the level set; it is evaluated as it will act, with
        # the verified states added (agents.control.handover)
        check = {k: handover[k] for k in ("verify", "verify_level")}
        train_env = HandOverVecEnv(train_env, handover["level"], handover["shaping"], gamma)
        eval_env = HandOverVecEnv(eval_env, handover["level"], **check)
    if hp.get("feedforward"):  # the agent's action around the operating input
        from .feedforward import FeedForwardVecEnv

        train_env, eval_env = FeedForwardVecEnv(train_env), FeedForwardVecEnv(eval_env)
    # the scale applies to everything the agent is paid, the hand-over's shaping included
    train_env = task_reward(train_env, env_id, hp)
    if train_env.__class__.__name__ == "TaskRewardVecEnv":  # SB3 syncs the statistics
        from .shaping import TaskRewardVecEnv  # through wrappers of the same depth

        eval_env = TaskRewardVecEnv(eval_env)  # the env's own rewards
    norm = _normalize_kwargs(hp)
    if norm is not None:
        center = norm.pop("center")
        train_env = VecNormalize(train_env, **norm)
        eval_env = VecNormalize(eval_env, **{**norm, "training": False, "norm_reward": False})
        if not center:
            from .uncentered import uncentered

            train_env, eval_env = uncentered(train_env), uncentered(eval_env)
    return train_env, eval_env
