"""The built-in tasks, each a `Task` declared on the engine's public API (`envs.task`) with
its drawing; `envs` registers them (`CURRENT`: the current version of each; `OLDER`: the
versions kept registered to compare)."""

from . import acrobot, arm, bead, bicycle, crank, disk

CURRENT = {
    "Lagrange/TwoLinkArm-v1": arm.TASK,
    "Lagrange/Acrobot-v2": acrobot.TASK_V2,
    "Lagrange/RollingDisk-v1": disk.TASK,
    "Lagrange/BeadOnRod-v1": bead.TASK,
    "Lagrange/CrankSlider-v1": crank.TASK,
    "Lagrange/Bicycle-v0": bicycle.TASK,
}
OLDER = {"Lagrange/Acrobot-v1": acrobot.TASK}  # the 3 N*m elbow: hard, kept to compare

MODULES = ("arm", "acrobot", "disk", "bead", "crank", "bicycle")
"""The modules of the built-in tasks, each documented by its docstring (`envs.docs`)."""
