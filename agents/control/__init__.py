"""Control: linear analysis, LQR, planning and tracking, closed loop, hand-over to LQR,
the heuristic baselines, and the recording an identification fits."""
