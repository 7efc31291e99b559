"""The one condensed system every builder returns: contact operators of one configuration.

``fe.general.condensation.condense`` (the hinge, from nodal compliances, with rigid
amplitudes), ``fe.structure.twobody.condense`` (two elastic bodies, by block solves) and the
bearing hinge's builders produce a ``Condensed``; :mod:`fe.contact` solves on its ``W``,
``w0`` and ``G``. ``BLOCK_RHS`` is the block size of the solves that form them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from fe.surfaces.geometry import ContactGeometry

FloatArray = npt.NDArray[np.float64]

BLOCK_RHS = 128
"""Right-hand sides per block solve when condensing (see benchmarks/bench_assembly.py).

Also the best of 32 to 512 for the general hinge's pin solves
(``fe.general.condensation.pin_delassus``), with the same W to the bit
(benchmarks/bench_assembly.txt, 'BLOCK_RHS')."""


@dataclass(frozen=True)
class Condensed:
    """A system condensed on the contact points of one configuration.

    Attributes:
        geo: The contact points (m of them).
        C: Contact operator on all DOFs, shape (3m, n_dof), CSR: local relative
            displacement (slave − master) in frames [n, t1, t2].
        W: Delassus operator, shape (3m, 3m), float64 [mm/N].
        w0: Relative displacement at zero force, shape (m, 3) [mm] (``g0`` in the normal
            column, zeros elsewhere).
        wall_s: Condensation time [s].
        G: Rigid map, shape (3m, k) [mm per unit α] (the hinge: the pin's six modes then
            the grip, k = 7); shape (3m, 0) for a system without rigid amplitudes.
        outside: Points outside the contact window (None: no window).
        C_outside: Their contact operator, shape (3 m_out, n_dof).
        locked: Directions whose ``C`` row vanishes on the free DOFs, shape (3m,), bool
            (None where the builder has none).
        locked_compliance: Diagonal of ``W`` given to locked directions [mm/N].
    """

    geo: ContactGeometry
    C: sp.csr_matrix
    W: FloatArray
    w0: FloatArray
    wall_s: float
    G: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    outside: ContactGeometry | None = None
    C_outside: sp.csr_matrix | None = None
    locked: npt.NDArray[np.bool_] | None = None
    locked_compliance: float = 0.0

    def __post_init__(self) -> None:
        if self.G.shape == (0, 0):  # no rigid amplitudes
            object.__setattr__(self, "G", np.zeros((self.W.shape[0], 0)))
