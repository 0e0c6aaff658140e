"""A test's env with its fused step bound at once: a new task's first
`envs.step.SEPARATE_FIRST` steps are otherwise separate calls, so a short test that
means to check the fused step would check the separate calls twice."""


def bound(env):
    """`env` (single or vector, wrapped or not) stepping with its fused step from now on."""
    rt = env.unwrapped._rt
    assert rt.stepper.fused is not None, "this env has no fused step"
    rt.stepper.bind(rt.parameters.model_params, rt.parameters.task_params)
    return env
