"""The general hinge condensed onto its contact points: factorise once, reuse for every load.

Boundary conditions (a tensile test machine with rigid grips): every DOF of the tang's
fixed face is zero; the clevis load face is held in y and z and moves rigidly in x by
δ. The pin is held only by contact.

Unknowns of the condensed problem (see ``fe.contact`` for conventions):

* contact forces ``p`` (m, 3) at the pin's surface nodes, in local frames
  ``[n, t1, t2]`` with ``n`` the hole's outward normal (into the hole), ``t1``
  circumferential, ``t2 = n × t1``;
* seven rigid amplitudes ``α``: the pin's six rigid-body modes (translations [mm] and
  rotations about its centre [rad]) and the grip displacement δ [mm].

Why this is exact, not stabilised:

* The clevis, with its grip face fixed, and the tang are non-singular; moving the grip
  by δ translates the clevis rigidly (it touches nothing else), so ``u_δ`` is a rigid
  translation and costs no strain energy.
* The pin is supported on six DOFs in a 3-2-1 pattern only to factorise it. For a
  self-equilibrated load (``Rᵀ f = 0``, enforced as ``Gᵀ p = e``) the supported solution is
  an exact solution of the floating pin, and the rigid part is ``R α``. The reactions at
  the six supports are then zero to round-off (checked by ``support_reaction``).
* Force control: ``G_δᵀ p = −F`` is the clevis' equilibrium, so the force is reached
  exactly in every increment, and in the free play (no contact) δ is a zero-energy
  direction that the solver resolves by minimum norm.

Clearance: each load direction is linearised about its own *touching configuration*
(pin pushed +Δr against the tang's +x side and the clevis a further +Δr, for tension;
mirrored for compression). Gaps are measured from the exact cylinders in that
configuration, so the second-order term Δr²sin²θ/(2R) that a single linearisation about
the centred pin would miss is included. The two configurations coincide at Δr = 0.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.errors import MeshQualityError
from cad.model import PairKind, SurfacePair
from cad.surfaces import Cylinder
from fe.assembly import assemble_stiffness, dofs_of
from fe.element import ElementType
from fe.linalg.sparse import Factorization, inverse_block
from fe.structure.condensed import BLOCK_RHS, Condensed
from fe.structure.supports import rigid_modes, three_two_one
from mesh.hexmesh import HexMesh

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

N_PIN_MODES = 6
"""Rigid-body modes of the floating pin: translations x, y, z, then rotations about x, y, z."""

GRIP = 6
"""Index of the grip displacement δ [mm] among the rigid amplitudes α (after the pin modes)."""

N_RIGID = N_PIN_MODES + 1
"""Rigid amplitudes of the hinge's condensed problem: the pin's six modes and the grip."""

RECOVER_BLOCK = 32
"""Right-hand sides per block solve when recovering displacements (bounds the work memory)."""

LOW_MEMORY_DOF = 400_000
"""Above this many DOF, ``build_system`` holds one part's sparse factor at a time.

On a mesh of about a million DOF (refinement 2 before the pin's band) both parts' factors
together with the dense contact operators did not fit in memory; one at a time they did
(benchmarks/bench_cycle.txt, 'LOW_MEMORY_DOF'). The price is a refactorisation per
displacement recovery, so recover many states at once (``displacements``)."""


def outside_gaps(cond: Condensed, u: FloatArray) -> FloatArray:
    """Normal gaps of the points outside the contact window, shape (m_out,) [mm]."""
    if cond.outside is None or cond.C_outside is None:
        return np.zeros(0)
    w = cond.C_outside @ np.ravel(u)
    return np.asarray(cond.outside.g0 + w[0::3])


TANG = "tang"
"""Name of the fixed lug part (its hole is the master surface of the tang-side pair)."""


def is_tang_side(pair: SurfacePair) -> bool:
    """True for the pin–tang contact pair (its master face belongs to the tang)."""
    return pair.master.startswith(TANG)


@dataclass
class HingeSystem:
    """The factorised hinge, ready to be condensed in any configuration.

    Attributes:
        mesh: The mesh.
        K: Global stiffness, shape (n_dof, n_dof) [N/mm].
        lug_free: Free DOFs of tang and clevis, shape (n_L,).
        pin_free: Free DOFs of the pin (all but the 3-2-1 supports), shape (n_P,).
        pin_support: The six supported pin DOFs.
        pin_R: Pin rigid modes on all DOFs, shape (n_dof, 6).
        u_grip: Unit grip displacement field (clevis translated +x), shape (n_dof,).
        lug_factor: Factorisation of K on ``lug_free`` (made on first use).
        pin_factor: Factorisation of K on ``pin_free`` (made on first use).
        timings_s: Wall time of assembly and factorisation [s].
        low_memory: Release each part's sparse factor right after using it, so that at most
            one is alive (see ``LOW_MEMORY_DOF``); results are identical.
    """

    mesh: HexMesh
    K: sp.csr_matrix
    lug_free: IntArray
    pin_free: IntArray
    pin_support: IntArray
    pin_R: FloatArray
    u_grip: FloatArray
    slave_nodes: IntArray
    master_nodes: IntArray
    timings_s: dict[str, float] = field(default_factory=dict)
    cache_dir: Path | None = None
    _compliance: dict[str, tuple[FloatArray, FloatArray]] = field(default_factory=dict, repr=False)
    _factors: dict[str, Factorization] = field(default_factory=dict, repr=False)
    low_memory: bool = False

    @property
    def lug_factor(self) -> Factorization:
        """Factorisation of tang + clevis on ``lug_free``, made on first use and kept."""
        return self._factor("lug", self.lug_free)

    @property
    def pin_factor(self) -> Factorization:
        """Factorisation of the supported pin on ``pin_free``, made on first use and kept."""
        return self._factor("pin", self.pin_free)

    def _factor(self, name: str, free: IntArray) -> Factorization:
        """Return a factorisation, made on first use (its time adds to ``timings_s``).

        The condensation needs none (Schur complements, each released after use), so no
        sparse factor is alive while condensing: at refinement 2 (before the pin's band),
        holding both factors during the Schur complements did not fit in memory
        (benchmarks/bench_cycle.txt, 'HingeSystem._factor').
        """
        if name not in self._factors:
            t0 = time.perf_counter()
            self._factors[name] = Factorization(self.K[free][:, free])
            dt = time.perf_counter() - t0
            self.timings_s["factorisation"] = self.timings_s.get("factorisation", 0.0) + dt
            logger.info("factorised the %s (%d DOF) in %.2f s", name, len(free), dt)
        return self._factors[name]

    def solve_parts(self, f: FloatArray) -> FloatArray:
        """Solve ``K u = f`` on each part's free DOFs (zero at supports and grips).

        One part at a time, in blocks of ``RECOVER_BLOCK`` right-hand sides, so that in
        low-memory mode each factor is made once per call and released before the next.

        Args:
            f: Nodal forces, shape (n_dof,) or (n_dof, k) [N].

        Returns:
            Displacements of the same shape [mm] (pin on its 3-2-1 supports, no rigid part).
        """
        f2 = f.reshape(f.shape[0], -1)
        u = np.zeros(f2.shape)
        for name, free in (("lug", self.lug_free), ("pin", self.pin_free)):
            factor = self._factor(name, free)
            for start in range(0, f2.shape[1], RECOVER_BLOCK):
                cols = slice(start, start + RECOVER_BLOCK)
                u[free, cols] = factor.solve(f2[free, cols]).reshape(len(free), -1)
            del factor
            self.release_factor(name)
        return u.reshape(f.shape)

    def release_factor(self, name: str) -> None:
        """Drop the ``name`` part's sparse factor in ``low_memory`` mode (kept otherwise)."""
        if self.low_memory:
            self._factors.pop(name, None)

    def nodal_compliance(self) -> tuple[FloatArray, FloatArray]:
        """Return the compliances at the slave and master nodes, computed once and kept.

        ``S_slave = K_P⁻¹`` restricted to the DOFs of all slave nodes (pin supported 3-2-1)
        and ``S_master = K_L⁻¹`` restricted to the DOFs of all master nodes, shapes
        (3 n_s, 3 n_s) and (3 n_m, 3 n_m) [mm/N]. They depend on the mesh only, so every
        configuration, amplitude and friction coefficient reuses them.
        """
        return self.compliance(self.slave_nodes, self.master_nodes)

    def compliance(
        self, slave_nodes: IntArray, master_nodes: IntArray
    ) -> tuple[FloatArray, FloatArray]:
        """Return the compliances at given slave (pin) and master (lug) nodes.

        Args:
            slave_nodes: Sorted pin nodes, shape (n_s,).
            master_nodes: Sorted tang/clevis nodes, shape (n_m,).

        Returns:
            (S_slave (3 n_s, 3 n_s), S_master (3 n_m, 3 n_m)) [mm/N], kept in memory (and on
            disk with ``cache_dir``) by node set.
        """
        key = _nodes_key(slave_nodes, master_nodes)
        if key not in self._compliance:
            t0 = time.perf_counter()
            cached = self._cache_path(key)
            if cached is not None and cached.exists():
                with np.load(cached) as data:
                    pair = (data["slave"], data["master"])
                logger.info("nodal compliance read from %s", cached)
            else:
                pair = (
                    _restricted_inverse(
                        self.K, lambda: self.pin_factor, self.pin_free, dofs_of(slave_nodes)
                    ),
                    self.lug_compliance(master_nodes),
                )
                if cached is not None:
                    _save_atomic(cached, {"slave": pair[0], "master": pair[1]})
            self._compliance[key] = pair
            self.timings_s["compliance"] = (
                self.timings_s.get("compliance", 0.0) + time.perf_counter() - t0
            )
        return self._compliance[key]

    def lug_compliance(self, master_nodes: IntArray) -> FloatArray:
        """The lugs' compliance at ``master_nodes`` (sorted), shape (3 n_m, 3 n_m) [mm/N], not kept."""
        return _restricted_inverse(
            self.K, lambda: self.lug_factor, self.lug_free, dofs_of(master_nodes)
        )

    def has_compliance(self, slave_nodes: IntArray, master_nodes: IntArray) -> bool:
        """Whether :meth:`compliance` of these nodes is kept in memory (no solve, no read)."""
        return _nodes_key(slave_nodes, master_nodes) in self._compliance

    def _cache_path(self, nodes_key: str) -> Path | None:
        """Cache file of nodal compliances: keyed by the mesh's content, supports and node set."""
        if self.cache_dir is None:
            return None
        key = hashlib.sha256(
            (self.mesh.content_hash() + self.kind.value + nodes_key).encode()
            + self.pin_support.tobytes()
        ).hexdigest()[:32]
        return self.cache_dir / f"compliance_{key}.npz"

    kind: ElementType = ElementType.INCOMPATIBLE

    @property
    def clearance_mm(self) -> float:
        """Radial clearance Δr: hole minus pin radius of the exact contact cylinders [mm].

        Raises:
            MeshQualityError: If a contact pair is not two cylinders, or the pairs disagree.
        """
        values = set()
        for p in self.mesh.pairs:
            if p.kind is not PairKind.CONTACT:
                continue
            pin, hole = self.mesh.surfaces.get(p.slave), self.mesh.surfaces.get(p.master)
            if not (isinstance(pin, Cylinder) and isinstance(hole, Cylinder)):
                raise MeshQualityError(f"contact pair {p.name!r} is not pin and hole cylinders")
            values.add(round(hole.radius_mm - pin.radius_mm, 12) + 0.0)
        if len(values) != 1:
            raise MeshQualityError(f"the contact pairs give different clearances: {sorted(values)}")
        return values.pop()

    @property
    def n_dof(self) -> int:
        """Number of DOFs of the whole mesh."""
        return 3 * self.mesh.n_nodes


def build_system(
    mesh: HexMesh, kind: ElementType = ElementType.INCOMPATIBLE, *, cache_dir: Path | None = None
) -> HingeSystem:
    """Assemble and factorise the general hinge (tang + clevis with grips, supported pin).

    Args:
        mesh: A general hinge mesh.
        kind: Element formulation.
        cache_dir: Folder where the nodal compliances are kept by the mesh's content
            hash, so another process (a sweep worker, a diagnosis, a rerun) reads them
            instead of solving again; None keeps them in memory only.

    Raises:
        MeshQualityError: If the mesh lacks the parts or faces of a general hinge.
    """
    for name in ("tang_fixed", "clevis_load"):
        if name not in mesh.facet_sets:
            raise MeshQualityError(f"the mesh has no facet set {name!r}: not a general hinge mesh")
    t0 = time.perf_counter()
    K = assemble_stiffness(mesh, kind)
    t_asm = time.perf_counter() - t0
    n_dof = 3 * mesh.n_nodes
    lug_nodes = np.concatenate([mesh.part_nodes("tang"), mesh.part_nodes("clevis")])
    fixed = dofs_of(np.concatenate([mesh.set_nodes("tang_fixed"), mesh.set_nodes("clevis_load")]))
    lug_free = np.setdiff1d(dofs_of(lug_nodes), fixed)
    pin_nodes = mesh.part_nodes("pin")
    x = np.asarray(mesh.nodes)[pin_nodes]
    support = three_two_one(mesh, pin_nodes)
    pin_free = np.setdiff1d(dofs_of(pin_nodes), support)
    centre = x.mean(axis=0)
    R = np.zeros((n_dof, N_PIN_MODES))
    R[dofs_of(pin_nodes)] = rigid_modes(x, centre)
    u_grip = np.zeros(n_dof)
    u_grip[3 * mesh.part_nodes("clevis")] = 1.0
    logger.info("assembled %d DOF in %.2f s", n_dof, t_asm)
    contact_pairs = [p for p in mesh.pairs if p.kind is PairKind.CONTACT]
    slave_nodes = np.unique(np.concatenate([mesh.set_nodes(p.slave) for p in contact_pairs]))
    master_nodes = np.unique(np.concatenate([mesh.set_nodes(p.master) for p in contact_pairs]))
    return HingeSystem(
        mesh,
        K,
        lug_free,
        pin_free,
        support,
        R,
        u_grip,
        slave_nodes,
        master_nodes,
        {"assembly": t_asm, "factorisation": 0.0},
        cache_dir=cache_dir,
        low_memory=n_dof > LOW_MEMORY_DOF,
        kind=kind,
    )


def _save_atomic(path: Path, arrays: dict[str, FloatArray]) -> None:
    """Write an .npz so that a reader never sees a half-written file (write, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    np.savez(tmp, slave=arrays["slave"], master=arrays["master"])
    os.replace(tmp, path)


def _restricted_inverse(
    K: sp.csr_matrix, factor: Callable[[], Factorization], free: IntArray, dofs: IntArray
) -> FloatArray:
    """Return (K_ff⁻¹)[dofs, dofs], shape (n, n), with zero rows/columns at supported DOFs.

    ``fe.assembly.inverse_block``: a Schur complement by partial factorisation with
    PARDISO, else blocks of ``BLOCK_RHS`` unit right-hand sides solved with ``factor()``.
    """
    pos = np.full(int(max(free.max(), dofs.max())) + 1, -1, dtype=np.int64)
    pos[free] = np.arange(len(free))
    local = pos[dofs]  # -1 where the DOF is supported (zero displacement)
    active = np.flatnonzero(local >= 0)
    block = inverse_block(K[free][:, free], local[active], factor=factor, block_rhs=BLOCK_RHS)
    if len(active) == len(dofs):  # no supported DOF: the block is the answer (no 2nd copy)
        return block
    out = np.zeros((len(dofs), len(dofs)))
    out[np.ix_(active, active)] = block
    return out


def _nodes_key(slave_nodes: IntArray, master_nodes: IntArray) -> str:
    return hashlib.sha256(slave_nodes.tobytes() + b"|" + master_nodes.tobytes()).hexdigest()[:16]


def displacement(
    system: HingeSystem, cond: Condensed, p: FloatArray, alpha: FloatArray
) -> FloatArray:
    """Recover the nodal displacement field, shape (n_nodes, 3) [mm].

    Args:
        system: The factorised hinge.
        cond: The configuration's condensed operators.
        p: Contact forces, shape (m, 3) [N].
        alpha: Rigid amplitudes (pin modes, grip), shape (7,).
    """
    return displacements(system, [(cond, p, alpha)])[0]


def displacements(
    system: HingeSystem, states: Sequence[tuple[Condensed, FloatArray, FloatArray]]
) -> list[FloatArray]:
    """Recover the displacement fields of many states with one solve per part and block.

    Args:
        system: The factorised hinge.
        states: (condensed configuration, contact forces (m, 3) [N], rigid amplitudes (7,))
            per state.

    Returns:
        One nodal displacement field per state, shape (n_nodes, 3) [mm].
    """
    if not states:
        return []
    f = np.column_stack([cond.C.T @ np.ravel(p) for cond, p, _ in states])
    u = system.solve_parts(f)  # (n_dof, k)
    rigid = np.column_stack([np.asarray(a, dtype=np.float64) for _, _, a in states])  # (7, k)
    u += system.pin_R @ rigid[:N_PIN_MODES] + np.outer(system.u_grip, rigid[GRIP])
    return [u[:, j].reshape(-1, 3) for j in range(len(states))]


def support_reaction(system: HingeSystem, cond: Condensed, p: FloatArray, u: FloatArray) -> float:
    """Largest force at the pin's six supports [N]: zero if the pin is truly floating."""
    f = cond.C.T @ np.ravel(p)
    res = system.K @ np.ravel(u) - f
    return float(np.abs(res[system.pin_support]).max())
