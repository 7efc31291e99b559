"""Condense the general hinge on the contact points of a configuration: ``W``, ``w0``, ``G``.

``W = C_s S_slave C_sᵀ + C_m S_master C_mᵀ`` from the nodal compliances of the nodes the
points use, formed by blocks of rows (:func:`delassus`), or with the pin's part by block
solves where the compliance blocks do not fit in memory (:func:`pin_delassus`; the path
is chosen by :func:`fe.general.memory.condense_path`).
"""

from __future__ import annotations

import time

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from fe.assembly import dofs_of
from fe.general.memory import CondensePath, condense_path
from fe.general.system import HingeSystem
from fe.structure.condensed import BLOCK_RHS, Condensed
from fe.surfaces.geometry import ContactGeometry, contact_operator

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


CONDENSE_ROWS = 512
"""Rows of ``W`` formed at a time by :func:`delassus` (a few MB per temporary)."""


def delassus(
    Cs: sp.csr_matrix, S_slave: FloatArray, Cm: sp.csr_matrix, S_master: FloatArray
) -> FloatArray:
    """``W = ½ (V + Vᵀ)`` with ``V = C_s S_slave C_sᵀ + C_m S_master C_mᵀ``, by blocks of rows.

    Only ``W`` and blocks of ``CONDENSE_ROWS`` rows are allocated: the whole-matrix
    expression held three more arrays of W's size, which is what a zero-clearance level 2
    (a 36 000² W) cannot afford; the result is the same bit for bit. Measured:
    benchmarks/bench_cycle.txt, 'delassus'.

    Args:
        Cs: Contact operator's columns at the slave nodes' DOFs, shape (3m, b_s).
        S_slave: Compliance at those DOFs, shape (b_s, b_s) [mm/N].
        Cm: Contact operator's columns at the master nodes' DOFs, shape (3m, b_m).
        S_master: Compliance at those DOFs, shape (b_m, b_m) [mm/N].

    Returns:
        The Delassus operator, shape (3m, 3m), float64 [mm/N], exactly symmetric.
    """
    n = Cs.shape[0]
    W = np.empty((n, n))
    for i in range(0, n, CONDENSE_ROWS):
        rows = slice(i, min(i + CONDENSE_ROWS, n))
        W[rows] = (Cs @ (Cs[rows] @ S_slave).T).T
    return _symmetrised(_add_congruence(W, Cm, S_master))


def _add_congruence(W: FloatArray, C: sp.csr_matrix, S: FloatArray) -> FloatArray:
    """``W += C S Cᵀ`` in place, by blocks of ``CONDENSE_ROWS`` rows; returns W."""
    n = W.shape[0]
    for i in range(0, n, CONDENSE_ROWS):
        rows = slice(i, min(i + CONDENSE_ROWS, n))
        W[rows] += (C @ (C[rows] @ S).T).T
    return W


def _symmetrised(W: FloatArray) -> FloatArray:
    """``W ← ½ (W + Wᵀ)`` in place, by blocks of ``CONDENSE_ROWS`` rows; returns W."""
    n = W.shape[0]
    for i0 in range(0, n, CONDENSE_ROWS):
        i1 = min(i0 + CONDENSE_ROWS, n)
        mean = 0.5 * (W[i0:i1, i0:] + W[i0:, i0:i1].T)
        W[i0:i1, i0:] = mean
        W[i0:, i0:i1] = mean.T
    return W


def pin_delassus(system: HingeSystem, C: sp.csr_matrix, master_nodes: IntArray) -> FloatArray:
    """``W`` with its pin part ``C_p K_p⁻¹ C_pᵀ`` from block solves (``CondensePath.SOLVES``).

    Blocks of ``BLOCK_RHS`` rows of ``C_p`` (the contact operator on the pin's free DOFs)
    are solved with the pin's sparse factor and multiplied back into rows of ``W``; the
    lugs' part comes from the master nodes' compliance as in :func:`delassus`. No
    compliance block of the pin's nodes exists at any time (at zero clearance it is as
    large as ``W``). The same matrix as :func:`delassus` to round-off.

    Args:
        system: The factorised hinge (the pin's factor is made here if needed, and
            released after use in ``low_memory`` mode).
        C: Contact operator, shape (3m, n_dof).
        master_nodes: Sorted lug nodes the points use, shape (n_m,).

    Returns:
        The Delassus operator, shape (3m, 3m), float64 [mm/N], exactly symmetric.
    """
    S_master = system.lug_compliance(master_nodes)
    Cp = sp.csr_matrix(C[:, system.pin_free])
    CpT = sp.csc_matrix(Cp.T)
    n = C.shape[0]
    W = np.empty((n, n))
    factor = system.pin_factor
    for i in range(0, n, BLOCK_RHS):
        rows = slice(i, min(i + BLOCK_RHS, n))
        W[rows] = np.asarray(Cp @ factor.solve(CpT[:, rows].toarray())).T
    del factor
    system.release_factor("pin")
    return _symmetrised(_add_congruence(W, _columns(C, master_nodes), S_master))


def condense(
    system: HingeSystem, geo: ContactGeometry, excluded: ContactGeometry | None = None
) -> Condensed:
    """Condense the hinge on the contact points of a configuration.

    ``W = C_s S_slave C_sᵀ + C_m S_master C_mᵀ`` with the nodal compliances of the nodes
    the points use (computed once per node set) and this configuration's local operators;
    where those blocks cannot fit in memory, the pin's part by solves instead
    (:func:`fe.general.memory.condense_path`, :func:`pin_delassus`).

    Raises:
        ResourceError: If neither way of forming ``W`` fits in the available memory.

    Args:
        system: The factorised hinge.
        geo: The contact points solved for.
        excluded: Points left out of the contact window, kept to check that they stay open.
    """
    slave_nodes = np.unique(geo.slave)
    master_nodes = np.unique(geo.master_nodes)
    path = condense_path(system, slave_nodes, master_nodes, len(geo.slave))
    if path is CondensePath.COMPLIANCE:
        S_slave, S_master = system.compliance(slave_nodes, master_nodes)
        t1 = time.perf_counter()
        C = contact_operator(geo, system.n_dof)
        W = delassus(_columns(C, slave_nodes), S_slave, _columns(C, master_nodes), S_master)
    else:  # forming W by solves counts as compliance: no blocks to time apart
        C = contact_operator(geo, system.n_dof)
        t0 = time.perf_counter()
        W = pin_delassus(system, C, master_nodes)
        t1 = time.perf_counter()
        system.timings_s["compliance"] = system.timings_s.get("compliance", 0.0) + t1 - t0
    W.setflags(write=False)  # constant: the contact solver then checks it once per cycle
    G = np.column_stack([C @ system.pin_R, C @ system.u_grip])
    w0 = np.column_stack([geo.g0, np.zeros((len(geo.g0), 2))])
    outside = None if excluded is None or len(excluded.slave) == 0 else excluded
    C_out = None if outside is None else contact_operator(outside, system.n_dof)
    return Condensed(
        geo=geo,
        C=C,
        W=W,
        w0=w0,
        wall_s=time.perf_counter() - t1,
        G=G,
        outside=outside,
        C_outside=C_out,
    )


def _columns(C: sp.csr_matrix, nodes: IntArray) -> sp.csr_matrix:
    """Columns of C at the DOFs of ``nodes``, shape (3m, 3 len(nodes))."""
    return C[:, dofs_of(nodes)]
