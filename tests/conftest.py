"""Shared test settings: one BLAS/torch thread and SDL's dummy drivers (no screen in CI)."""

import os
import signal

import pytest

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def interactive_sigint():
    """SIGINT with Python's own handler (Ctrl-C raises KeyboardInterrupt), as in an
    interactive run: a shell without job control starts background jobs, as a CI runner may
    start the tests, with SIGINT ignored, and the training program respects that."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture(autouse=True)
def _background_compiles_end_with_their_test():
    """A fused step compiling in the background (envs.step) is bound before the next
    test starts: numba swaps the process's warning filters while it compiles, which a later
    test that expects a warning would otherwise meet."""
    yield
    from envs.step import wait_for_background

    wait_for_background()
