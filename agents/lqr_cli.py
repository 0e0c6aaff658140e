"""Deprecated: the LQR command line is `agents.lqr` (`python -m agents.lqr`)."""

import warnings

from .lqr import build_parser, describe, main, plot_response  # noqa: F401

warnings.warn(
    "agents.lqr_cli is deprecated; use agents.lqr (python -m agents.lqr).",
    DeprecationWarning,
    stacklevel=2,
)
