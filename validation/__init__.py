"""Validation: read measurements, measure loops the same way on both sides, compare.

Workflow: ``measurements`` reads a folder (``cases.csv`` + loop files, Bluehill
exports, η-only tables) → ``loops`` removes offsets, finds the stages and measures
W, U_max, η, δ(+Fg), secant stiffness → ``compare`` forms per-case errors against the
measurement uncertainty → ``plots`` draws them. ``model_file`` reads and writes the
MODEL.toml that ``hingelab compare`` runs.

>>> import numpy as np
>>> from validation.loops import process_loop
>>> F = np.array([0.0, 100.0, 0.0, -100.0, 0.0, 100.0])  # 0 → +Fg → −Fg → +Fg [N]
>>> d = np.array([0.0, 2.0, 1.0, -2.0, -1.0, 2.0]) * 1e-3  # a parallelogram loop [mm]
>>> m = process_loop(F, d, "doctest").metrics
>>> round(m.W_cycle_Nmm, 6), round(m.delta_max_mm, 6), round(m.eta, 4)
(0.2, 0.002, 0.3183)
"""
