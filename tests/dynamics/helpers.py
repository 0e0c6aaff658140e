"""Random states for the scleronomic models of issue 2 (shared by the dynamics tests)."""

import numpy as np

import dynamics


def random_states(name: str, count: int, seed: int = 0) -> tuple[dynamics.System, np.ndarray]:
    """`count` states: angles anywhere, rates up to a few rad/s (the disk: rolling upright-ish
    fast enough not to fall within 10 s, so that its motion stays regular)."""
    system = dynamics.get_model(name).compile()
    rng = np.random.default_rng(seed)
    n = system.n_q
    x = np.zeros((count, 2 * n))
    x[:, :n] = rng.uniform(-np.pi, np.pi, (count, n))
    x[:, n:] = rng.uniform(-3.0, 3.0, (count, n))
    if name == "rolling_disk":
        x[:, n : n + 2] = 0.0  # the projection below supplies the rolling xdot, zdot
    if name == "rolling_disk":
        x[:, 2] = np.pi / 2 + rng.uniform(-0.1, 0.1, count)
        x[:, n + 2] = rng.uniform(-0.5, 0.5, count)
        x[:, n + 3] = rng.uniform(-1.0, 1.0, count)
        x[:, n + 4] = rng.uniform(-20.0, -10.0, count)
        x = system.project(x)  # xdot, zdot consistent with rolling (eqs. 7.27-7.28)
    if name == "bead_on_driven_rod":
        x[:, 0] = rng.uniform(-0.8, 0.8, count)
    return system, x


SCLERONOMIC = ["two_link_arm", "rolling_disk", "bead_on_driven_rod"]
