"""Deprecated: the planning command line is `agents.plan` (`python -m agents.plan`)."""

import warnings

from .plan import build_parser, main, plot, run  # noqa: F401

warnings.warn(
    "agents.plan_cli is deprecated; use agents.plan (python -m agents.plan).",
    DeprecationWarning,
    stacklevel=2,
)
