"""How the general hinge's condensation fits in memory: estimates, the path, the switches.

Before any dense matrix is allocated, :func:`condense_path` compares what forming ``W``
needs (:func:`dense_memory_bytes` from the nodal compliance blocks, or
:func:`solves_memory_bytes` by pin solves) with what the kernel can give
(:func:`available_memory_bytes`), and refuses with a ``ResourceError`` where neither fits.
Two environment variables override it: ``HINGELAB_CONDENSE`` forces a path and
``HINGELAB_MEMORY_CHECK=0`` skips the check. (The system's low-memory mode, one sparse
factor alive at a time, is ``fe.general.system.LOW_MEMORY_DOF``.)
"""

from __future__ import annotations

import logging
import os
from enum import Enum

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError, ResourceError
from fe.general.system import HingeSystem

logger = logging.getLogger(__name__)

IntArray = npt.NDArray[np.int64]


MEMORY_CHECK_ENV = "HINGELAB_MEMORY_CHECK"
"""Set to ``0`` to skip the memory check of :func:`condense_path` (e.g. with swap the
estimate ignores)."""

CONDENSE_ENV = "HINGELAB_CONDENSE"
"""Set to ``compliance`` or ``solves`` to force a :class:`CondensePath`."""


def available_memory_bytes() -> int | None:
    """Memory the kernel can still give without swapping (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


CONTACT_PHASE_W = 1.0
"""Peak memory the contact phase adds to a zero-clearance cycle, in units of ``W``'s size.

The closed points' block of ``W`` or the working set's (one of them at a time), its
float32 copy, the float32 base LU and the next one. The value lies above the resident-set
peaks measured over the phase at levels 0–2 (benchmarks/bench_cycle.txt, 'CONTACT_PHASE_W'):
an estimate below the true peak lets through a cycle that the out-of-memory killer then ends."""


def dense_memory_bytes(b_s: int, b_m: int, n: int, *, compliance_kept: bool = False) -> int:
    """Peak of the dense matrices the condensation of one configuration allocates [bytes].

    Compliance blocks not yet kept each take their Schur complement and PARDISO's copy of
    it (the slave block's result is held while the master's is made); then both blocks
    and ``W`` are held while ``W`` is formed (:func:`fe.general.condensation.delassus`);
    the contact phase adds ``CONTACT_PHASE_W`` times ``W``.

    Args:
        b_s: Slave compliance DOFs.
        b_m: Master compliance DOFs.
        n: Rows of ``W`` (three per contact point).
        compliance_kept: The blocks are already in memory (not counted again).
    """
    blocks = 0 if compliance_kept else 8 * (b_s**2 + b_m**2)
    schur = 0 if compliance_kept else 8 * max(2 * b_s**2, b_s**2 + 2 * b_m**2)
    condense = blocks + 8 * n**2 + int(CONTACT_PHASE_W * 8 * n**2)
    return max(schur, condense)


def solves_memory_bytes(b_m: int, n: int) -> int:
    """Peak of the dense matrices of the condensation by pin solves [bytes].

    By :func:`fe.general.condensation.pin_delassus`: the master block's Schur complement
    and PARDISO's copy of it; then ``W`` and the master block while ``W`` is formed; then
    ``W`` and the contact phase's ``CONTACT_PHASE_W`` times ``W`` (the master block is
    released with the condensation). No slave block is formed.

    Args:
        b_m: Master compliance DOFs.
        n: Rows of ``W`` (three per contact point).
    """
    return 8 * max(2 * b_m**2, b_m**2 + n**2, int((1.0 + CONTACT_PHASE_W) * n**2))


class CondensePath(Enum):
    """How :func:`fe.general.condensation.condense` forms ``W``.

    COMPLIANCE: from the nodal compliance blocks of the slave (pin) and master (lug)
    nodes, each a Schur complement, kept by the system for every later configuration of
    the same nodes (fastest; needs both blocks and ``W`` in memory at once).
    SOLVES: the pin's part ``C_p K_p⁻¹ C_pᵀ`` by block solves with the pin's sparse factor
    (:func:`fe.general.condensation.pin_delassus`), written straight into ``W``, and only
    the master block as a Schur complement, released afterwards: about half the memory of
    COMPLIANCE at zero clearance, where the slave block is as large as ``W``, and slower.
    """

    COMPLIANCE = "compliance"
    SOLVES = "solves"


def condense_path(
    system: HingeSystem, slave_nodes: IntArray, master_nodes: IntArray, m: int
) -> CondensePath:
    """Choose how to condense, before allocating any dense matrix.

    COMPLIANCE where its matrices fit in the available memory (compliance blocks the
    system keeps are not counted again), else SOLVES where those fit, else raise.
    ``HINGELAB_CONDENSE`` (``compliance`` or ``solves``) forces a path;
    ``HINGELAB_MEMORY_CHECK=0`` or an unknown available memory takes COMPLIANCE unchecked.

    Raises:
        ResourceError: Neither path fits, naming the sizes, the estimates and the memory
            available.
        ParameterError: ``HINGELAB_CONDENSE`` names no path.
    """
    forced = os.environ.get(CONDENSE_ENV)
    if forced is not None:
        try:
            return CondensePath(forced)
        except ValueError:
            raise ParameterError(
                f"{CONDENSE_ENV} = {forced!r}: expected one of {[p.value for p in CondensePath]}"
            ) from None
    b_s, b_m, n = 3 * len(slave_nodes), 3 * len(master_nodes), 3 * m
    available = available_memory_bytes()
    if os.environ.get(MEMORY_CHECK_ENV, "1") == "0" or available is None:
        return CondensePath.COMPLIANCE
    kept = system.has_compliance(slave_nodes, master_nodes)
    need = dense_memory_bytes(b_s, b_m, n, compliance_kept=kept)
    if need <= available:
        return CondensePath.COMPLIANCE
    low = solves_memory_bytes(b_m, n)
    if low <= available:
        logger.info(
            "condensing %d points by pin solves: the compliance blocks would need %s, "
            "%s are available (this path needs %s)",
            m,
            _size(need),
            _size(available),
            _size(low),
        )
        return CondensePath.SOLVES
    raise ResourceError(
        f"condensing {m} contact points needs about {_size(need)} of dense matrices "
        f"(compliance blocks of {b_s} and {b_m} DOFs, W of {n}² entries), or {_size(low)} "
        f"by pin solves, and {_size(available)} are available: use a coarser mesh "
        f"(refinement), or a clearance with a contact window (CycleSettings.contact_window) "
        f"so that fewer points are condensed; {MEMORY_CHECK_ENV}=0 skips this check"
    )


def _size(n_bytes: int) -> str:
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e8 else f"{n_bytes / 1e6:.1f} MB"
