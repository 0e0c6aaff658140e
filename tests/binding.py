"""A test's env with its fused step bound at once: a new task's first
`envs.compiled.SEPARATE_FIRST` steps are otherwise separate calls, so a short test that
means to check the fused step would check the separate calls twice."""

from envs import compiled


def bound(env):
    """`env` (single or vector, wrapped or not) stepping with its fused step from now on."""
    rt = env.unwrapped._rt
    assert rt._fused is not None, "this env has no fused step"
    compiled.bind_fused(rt)
    return env
