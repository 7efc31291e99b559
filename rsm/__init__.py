"""Response surfaces of the loss factor η: design, fit, check, query, plot, trace.

The workflow, on a tiny exact quadratic ``y = 1 + 2·x1 - 3·x2 + 0.5·x1·x2`` sampled
on a 3 × 3 full factorial design:

>>> import numpy as np
>>> from rsm.design import full_factorial
>>> from rsm.polynomial import fit_response_surface, predict
>>> from rsm.metrics import fit_metrics
>>> x = full_factorial([[0.0, 0.1, 0.2], [100.0, 200.0, 300.0]])  # (9, 2): mm, N
>>> y = 1 + 2 * x[:, 0] - 3 * x[:, 1] + 0.5 * x[:, 0] * x[:, 1]
>>> s = fit_response_surface(x, y, degree=2, x_names=("clearance_mm", "amplitude_N"))
>>> s.term_names
('1', 'x1', 'x2', 'x1^2', 'x1*x2', 'x2^2')
>>> print(f"{s.coefficients[4]:.6f}")  # the x1*x2 coefficient, physical units
0.500000
>>> m = fit_metrics(s)  # warns (OverfitWarning) if the fit looks over-fitted
>>> print(f"R2 = {m.r2:.6f}")
R2 = 1.000000

Modules, in pipeline order: :mod:`rsm.tables` (read and validate CSV tables),
:mod:`rsm.design` (full factorial, Latin hypercube, central composite,
Box–Behnken via pyDOE3), :mod:`rsm.polynomial` (terms, design matrix, fit,
predict, gradient; the frozen :class:`~rsm.polynomial.ResponseSurface`),
:mod:`rsm.metrics` (the paper's Eqs. 7-12 plus leave-one-out PRESS/Q² and an
over-fitting warning), :mod:`rsm.query` (extremes, threshold regions, best
design), :mod:`rsm.plots` (PNG figures), :mod:`rsm.paper` (the comparison with
the paper's printed numbers) and :mod:`rsm.trace` (the SQLite chain from a
sample point back to its STEP file, mesh and loop).
"""
