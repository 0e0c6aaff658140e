"""A trained stable-baselines3 run as a policy with the `predict` interface of
`agents.control.policies`: the model, its VecNormalize statistics and its LQR hand-over,
read back from the run directory and checked against the env it will act in."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..common import UserError


class SB3Policy:
    """A trained stable-baselines3 model with its VecNormalize observation statistics."""

    def __init__(self, model, obs_rms=None, clip_obs: float = 10.0, epsilon: float = 1e-8):
        self.model = model
        self.obs_rms = obs_rms
        self.clip_obs, self.epsilon = clip_obs, epsilon
        self.handover: dict | None = None  # the run's LQR hand-over (agents.control.handover)
        self.feedforward = False  # the run's feed-forward (agents.learning.feedforward)

    @classmethod
    def load(cls, path: str | Path, env=None) -> SB3Policy:
        """Load model.zip (the algorithm read from config.yml beside it, or tried in turn)
        and vecnormalize.pkl if it is there. With `env` (the env it will act in), the run
        must have been trained on its id and version, with its spaces and observation size.
        Every problem is a one-line UserError.

        Both files are pickles: loading them runs code, so load only runs you trust."""
        from ..learning.hparams import algorithms
        from ..learning.rundir import check_run_is_for, read_config

        path = Path(path)
        if path.is_dir():
            path = path / "model.zip"
        if not path.is_file():
            raise FileNotFoundError(f"No trained model at {path}.")
        run = read_config(path.parent)
        env_id = _env_id(env)
        check_run_is_for(path.parent, run, env_id)
        algos = algorithms()
        order = list(dict.fromkeys([run.get("algo", "ppo"), *algos]))
        model, errors = None, []
        for name in order:
            try:
                model = algos[name].load(path, device="cpu")
                break
            except Exception as exc:  # a damaged zip: BadZipFile, EOFError, UnpicklingError
                errors.append(f"{name}: {' '.join(str(exc).split())[:120] or type(exc).__name__}")
        if model is None:
            raise UserError(f"{path} is not a PPO, SAC or TD3 model ({'; '.join(errors)}).")
        if env is not None:
            _check_spaces(path, model, env)
        policy = cls(model)
        stats = path.parent / "vecnormalize.pkl"
        if stats.exists():
            vecnorm = _read_vecnormalize(stats)
            if vecnorm.norm_obs:
                if np.shape(vecnorm.obs_rms.mean) != model.observation_space.shape:
                    raise UserError(
                        f"{stats} normalises observations of shape "
                        f"{np.shape(vecnorm.obs_rms.mean)}; the model's are "
                        f"{model.observation_space.shape}: it is from another run."
                    )
                policy = cls(model, vecnorm.obs_rms, vecnorm.clip_obs, vecnorm.epsilon)
        policy.handover = (run.get("hyperparams") or {}).get("handover")
        policy.feedforward = bool((run.get("hyperparams") or {}).get("feedforward"))
        return policy

    @classmethod
    def of_model(cls, model, handover: dict | None = None, feedforward=False) -> SB3Policy:
        """The policy of a model in training, with a copy of its normalisation statistics
        as they are now (what a save would write) and the run's hand-over."""
        import copy

        vecnorm = model.get_vec_normalize_env()
        policy = cls(model)
        if vecnorm is not None and vecnorm.norm_obs:
            rms = copy.deepcopy(vecnorm.obs_rms)
            policy = cls(model, rms, vecnorm.clip_obs, vecnorm.epsilon)
        policy.handover, policy.feedforward = handover, bool(feedforward)
        return policy

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_rms is None:
            return obs
        z = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation, dtype=np.float32)
        return self.model.predict(self.normalize(obs), state, episode_start, deterministic)


def with_handover(policy: SB3Policy, env):
    """`policy` acting as it was trained to: handing over to LQR where its run declares a
    hand-over (agents.control.handover) and adding its feed-forward
    (agents.learning.feedforward), built for `env`."""
    handover, acting = policy.handover, policy
    if policy.feedforward:
        from ..learning.feedforward import FeedForwardPolicy

        acting = FeedForwardPolicy(policy, env)
    if handover is None:
        return acting
    from ..control.handover import HandOverPolicy, handover_options

    h = handover_options(handover)
    return HandOverPolicy(acting, env, h["level"], h["verify"], h["verify_level"])


def _env_id(env) -> str | None:
    spec = getattr(env, "spec", None) or getattr(getattr(env, "unwrapped", None), "spec", None)
    return getattr(spec, "id", None)


def _check_spaces(path: Path, model, env) -> None:
    """UserError when the model's observation or action space differs from the env's."""
    obs = getattr(env, "single_observation_space", env.observation_space)
    act = getattr(env, "single_action_space", env.action_space)
    if model.observation_space.shape != obs.shape or model.action_space.shape != act.shape:
        raise UserError(
            f"{path} was trained on observations {model.observation_space.shape} and actions "
            f"{model.action_space.shape}; the env has {obs.shape} and {act.shape}: it was "
            "trained on another environment."
        )


def _read_vecnormalize(path: Path):
    """A VecNormalize pickle (SB3's format), or UserError for a damaged or foreign file."""
    import pickle

    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as fh:
            vecnorm = pickle.load(fh)
    except Exception as exc:  # truncated: EOFError, UnpicklingError; foreign: anything
        raise UserError(
            f"{path} cannot be read ({type(exc).__name__}: {str(exc)[:80]}); it is damaged "
            "or not normalisation statistics."
        ) from None
    if not isinstance(vecnorm, VecNormalize):
        raise UserError(f"{path} holds a {type(vecnorm).__name__}, not VecNormalize statistics.")
    return vecnorm
