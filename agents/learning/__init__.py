"""Learning: training internals, hyperparameters (hyperparams/*.yml) and the task-derived
defaults, shaping, the time budget, vector envs, curves, fingerprints and the run directory."""
