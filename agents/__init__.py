"""Controllers and learning agents for the lagrange-gym environments (LQR, baselines, SB3)."""
