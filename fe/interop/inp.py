"""Write a meshed hinge as an ABAQUS/CalculiX input deck (``.inp``), plain and commented.

What goes where (``**`` lines in the deck say the same next to each block):

* ``*NODE``: our node ``i`` is deck node ``i + 1``; ``*ELEMENT, TYPE=C3D8I``: our element
  ``e`` is deck element ``e + 1``, one ELSET per part. C3D8I is the incompatible-modes
  hexahedron of ABAQUS and CalculiX, the counterpart of ``fe.element``'s default. The
  C3D8 node order is the VTK order of ``mesh.hexmesh`` (bottom face 1-2-3-4
  counter-clockwise seen from +ζ, top face 5-8 above it), so connectivity is copied as is.
* Every facet set becomes an NSET (its nodes) and an element-face ``*SURFACE`` of the same
  name (``elem, S1`` … ``S6``, see ``C3D8_FACES``).
* Each contact pair: a ``*SURFACE INTERACTION`` and a ``*CONTACT PAIR`` with slave = pin
  side, master = hole side; each bonded pair a ``*TIE``. The penalty types (node-to-surface,
  the default, and surface-to-surface) get a penalty normal law and Coulomb friction with
  a stick slope, a regularisation our solver does not have; ``DeckSettings.exact_mortar()``
  writes ccx's mortar contact with hard contact and exact stick instead, the counterpart
  of our Lagrange-multiplier solver (docs/calculix_crosscheck.md).
* Boundary conditions as in our solver: FIXED faces fully fixed; the LOAD face (the grip)
  held in the two directions across its normal and moved rigidly along it (``*EQUATION``
  ties every node to a reference node that carries the force, so the total force on the
  face is Fg).
* Parts with neither a FIXED nor a LOAD face (the pin) are held only by contact. A direct
  solver needs something for their rigid modes before contact closes: weak grounded
  springs (``SPRING1``) on all their nodes, ``float_spring_n_per_mm`` in total per
  direction. With clearance the grip also floats across the free play, so it gets a
  grounded spring too, and its ``*CLOAD`` is raised by that spring's force at the
  touching configuration (k·2Δr) so that the hinge itself carries ±Fg at the peaks.
* Three ``*STEP`` blocks: 0 → +Fg → −Fg → +Fg (a static step ramps a ``*CLOAD`` linearly
  from the previous step's value), each printing the grip displacement and the total
  reaction of the FIXED faces (= the force through the hinge) per increment to the
  ``.dat`` file, which ``fe.interop.ccx`` reads.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cad.errors import MeshQualityError, ParameterError
from cad.materials import Material
from cad.model import FaceRole, NamedFace, PairKind
from cad.surfaces import Plane
from fe.interop.deck_settings import (
    EXACT_STICK_SLOPE_MPA_PER_MM,
    ContactType,
    DeckSettings,
)
from fe.interop.inp_names import GRIP_REF_SET, Roles, inp_name, num
from fe.interop.inp_steps import steps
from mesh.hexmesh import HexMesh

__all__ = [
    "C3D8_FACES",
    "deck_text",
    "facet_element_faces",
    "write_deck",
]

IntArray = npt.NDArray[np.int64]

C3D8_FACES: tuple[tuple[int, int, int, int], ...] = (
    (0, 1, 2, 3),
    (4, 7, 6, 5),
    (0, 4, 5, 1),
    (1, 5, 6, 2),
    (2, 6, 7, 3),
    (3, 7, 4, 0),
)
"""Local (0-based) nodes of the C3D8 faces S1 … S6, as ABAQUS and CalculiX number them::

        8 -------- 7          S1 = 1-2-3-4  (ζ = −1)    S4 = 2-6-7-3  (ξ = +1)
       /|         /|          S2 = 5-8-7-6  (ζ = +1)    S5 = 3-7-8-4  (η = +1)
      5 -------- 6 |          S3 = 1-5-6-2  (η = −1)    S6 = 4-8-5-1  (ξ = −1)
      | 4 -------|-3
      |/         |/           (1-based, the deck's numbering; the VTK order of
      1 -------- 2            mesh.hexmesh with every index + 1)
"""

_PER_LINE = 8


def facet_element_faces(mesh: HexMesh, facets: IntArray) -> tuple[IntArray, IntArray]:
    """Find the element and C3D8 face (1 … 6) that each boundary facet is.

    Args:
        mesh: The mesh.
        facets: Quad facets, shape (n, 4), int64, our node indices.

    Returns:
        (element indices (n,) int64, 0-based; face numbers (n,) int64 in 1 … 6).

    Raises:
        MeshQualityError: If a facet is no face of any element.
    """
    faces = mesh.hexes[:, np.array(C3D8_FACES)]  # (n_elem, 6, 4)
    key_all = np.sort(faces.reshape(-1, 4), axis=1)
    lookup = {tuple(k): i for i, k in enumerate(key_all.tolist())}
    found = [lookup.get(tuple(k), -1) for k in np.sort(facets, axis=1).tolist()]
    missing = [i for i, f in enumerate(found) if f < 0]
    if missing:
        raise MeshQualityError(
            f"{len(missing)} facet(s) are no element face, e.g. nodes {facets[missing[0]].tolist()}"
        )
    idx = np.asarray(found, dtype=np.int64)
    return idx // 6, idx % 6 + 1


def _rows(values: Iterable[object], per_line: int = _PER_LINE) -> list[str]:
    items = [str(v) for v in values]
    return [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]


def _load_axis(face: NamedFace) -> tuple[int, float]:
    """Return (deck DOF 1-3, sign) of a LOAD face's outward normal, which must be axis-aligned."""
    if not isinstance(face.surface, Plane):
        raise ParameterError(f"load face {face.name!r} must be a plane, got {face.surface!r}")
    n = np.asarray(face.surface.normal, dtype=np.float64)
    axis = int(np.argmax(np.abs(n)))
    if not math.isclose(abs(n[axis]), float(np.linalg.norm(n)), rel_tol=1e-12):
        raise ParameterError(f"load face {face.name!r} normal must lie along x, y or z, got {n}")
    return axis + 1, float(np.sign(n[axis]))


def _roles(mesh: HexMesh, faces: Mapping[str, NamedFace]) -> Roles:
    named = {n: faces[n] for n in mesh.facet_sets if n in faces}
    fixed = tuple(sorted(n for n, f in named.items() if f.role is FaceRole.FIXED))
    load = sorted(n for n, f in named.items() if f.role is FaceRole.LOAD)
    if not fixed:
        raise ParameterError(f"the mesh has no FIXED facet set; sets are {sorted(mesh.facet_sets)}")
    if len(load) != 1:
        raise ParameterError(f"the mesh needs exactly one LOAD facet set, got {load}")
    held = {named[n].part for n in (*fixed, *load)}
    floating = tuple(p for p in mesh.part_names if p not in held)
    return Roles(fixed, load[0], floating)


def _header(mesh: HexMesh, s: DeckSettings, title: str) -> list[str]:
    return [
        "*HEADING",
        title or "hingelab hinge model",
        "** Written by hingelab (fe.interop.inp). Units: mm, N, MPa, s.",
        f"** {mesh.n_nodes} nodes, {mesh.n_elem} C3D8I elements, parts {', '.join(mesh.part_names)}.",
        f"** Load: 0 -> +{s.amplitude_n:g} N -> -{s.amplitude_n:g} N -> +{s.amplitude_n:g} N, "
        f"mu = {s.mu:g}, clearance = {s.clearance_mm:g} mm.",
        "** Our node i is deck node i+1, our element e is deck element e+1.",
    ]


def _geometry(mesh: HexMesh) -> list[str]:
    out = ["**", "** ---- Nodes [mm] ----", "*NODE, NSET=all_nodes"]
    out += [f"{i + 1}, {num(x)}, {num(y)}, {num(z)}" for i, (x, y, z) in enumerate(mesh.nodes)]
    out += ["**", "** ---- Elements: C3D8I (incompatible modes), one ELSET per part ----"]
    out += ["** Node order C3D8 = VTK hexahedron: 1-2-3-4 bottom, 5-6-7-8 above them."]
    for p in mesh.part_names:
        out += [f"*ELEMENT, TYPE=C3D8I, ELSET={inp_name(p)}"]
        out += [
            f"{e + 1}, " + ", ".join(str(n + 1) for n in mesh.hexes[e])
            for e in mesh.part_elements(p)
        ]
    return out


def _sets(mesh: HexMesh) -> list[str]:
    out = ["**", "** ---- Named sets: each facet set as an NSET and an element-face SURFACE ----"]
    for name in sorted(mesh.facet_sets):
        label = inp_name(name)
        elem, face = facet_element_faces(mesh, mesh.facet_sets[name])
        out += [f"** {name}: {len(face)} facets, {len(mesh.set_nodes(name))} nodes"]
        out += [f"*NSET, NSET={label}", *_rows(mesh.set_nodes(name) + 1)]
        out += [f"*SURFACE, NAME={label}, TYPE=ELEMENT"]
        out += [f"{e + 1}, S{f}" for e, f in zip(elem.tolist(), face.tolist(), strict=True)]
    for name in sorted(mesh.node_sets):
        out += [f"*NSET, NSET={inp_name(name)}", *_rows(np.unique(mesh.node_sets[name]) + 1)]
    return out


def _materials(mesh: HexMesh) -> list[str]:
    out = ["**", "** ---- Materials (isotropic linear elastic, MPa) and solid sections ----"]
    labels: dict[Material, str] = {}
    for m in mesh.materials:
        if m not in labels:
            labels[m] = inp_name("mat_" + m.name)
            out += [
                f"*MATERIAL, NAME={labels[m]}",
                "*ELASTIC",
                f"{num(m.young_mpa)}, {num(m.poisson)}",
            ]
    for p, m in zip(mesh.part_names, mesh.materials, strict=True):
        out += [f"*SOLID SECTION, ELSET={inp_name(p)}, MATERIAL={labels[m]}"]
    return out


def _normal_law(s: DeckSettings) -> list[str]:
    """The ``*SURFACE BEHAVIOR`` lines (none: the mortar method's hard contact)."""
    if s.penalty_mpa_per_mm is None:
        return [
            "** Normal: hard contact (no *SURFACE BEHAVIOR: the mortar method's Lagrange",
            "** multipliers enforce zero penetration, as our solver does).",
        ]
    law = num(s.penalty_mpa_per_mm)
    if s.contact is ContactType.NODE_TO_SURFACE:
        law += f", {num(s.tension_mpa)}"
    return [
        "** Normal: penalty, pressure = slope x overclosure [MPa/mm]"
        + (", then the tension for open gaps [MPa]." if "," in law else "."),
        "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
        law,
    ]


def _friction(s: DeckSettings) -> list[str]:
    """The ``*FRICTION`` lines (none without friction)."""
    if s.mu == 0.0:
        return []
    if s.stick_slope_mpa_per_mm is None:
        return [
            "** Friction: Coulomb mu; the stick slope is so large that stick is exact (the",
            "** mortar method takes its inverse as a tangential compliance).",
            "*FRICTION",
            f"{num(s.mu)}, {num(EXACT_STICK_SLOPE_MPA_PER_MM)}",
        ]
    return [
        "** Friction: Coulomb mu, then the stick slope [MPa/mm] (elastic slip before sliding;",
        "** our solver sticks exactly, so a stiffer slope is closer to it).",
        "*FRICTION",
        f"{num(s.mu)}, {num(s.stick_slope_mpa_per_mm)}",
    ]


def _interactions(mesh: HexMesh, s: DeckSettings) -> list[str]:
    out: list[str] = []
    for pair in mesh.pairs:
        slave, master = inp_name(pair.slave), inp_name(pair.master)
        if pair.kind is PairKind.BONDED:
            out += [
                "**",
                f"** ---- Bonded pair {pair.name}: tied ({pair.slave} follows {pair.master}) ----",
                f"*TIE, NAME={inp_name('tie_' + pair.name)}",
                f"{slave}, {master}",
            ]
            continue
        name = inp_name("contact_" + pair.name)
        out += [
            "**",
            f"** ---- Contact pair {pair.name}: slave {pair.slave} (pin side), "
            f"master {pair.master} (hole side) ----",
            f"*SURFACE INTERACTION, NAME={name}",
            *_normal_law(s),
            *_friction(s),
        ]
        head = f"*CONTACT PAIR, INTERACTION={name}, TYPE={s.contact.value}"
        if s.adjust_mm > 0.0:
            out += [
                f"** ADJUST: slave nodes within {s.adjust_mm:g} mm of the master facets, or"
                " penetrating them, start on them."
            ]
            head += f", ADJUST={num(s.adjust_mm)}"
        out += [head, f"{slave}, {master}"]
    return out


def _boundary(mesh: HexMesh, faces: Mapping[str, NamedFace], roles: Roles) -> list[str]:
    dof, _ = _load_axis(faces[roles.load])
    across = [d for d in (1, 2, 3) if d != dof]
    grip = mesh.set_nodes(roles.load) + 1
    ref = int(grip[0])
    out = ["**", "** ---- Boundary conditions (a tensile machine with rigid grips) ----"]
    for name in roles.fixed:
        out += [f"** {name}: fully fixed.", "*BOUNDARY", f"{inp_name(name)}, 1, 3"]
    out += [
        f"** {roles.load}: held in DOFs {across[0]} and {across[1]}; moves rigidly along DOF {dof}:",
        f"** every node's DOF {dof} equals that of node {ref} (NSET {GRIP_REF_SET}), which carries the",
        "** force, so the total force on the face is the *CLOAD.",
        f"*NSET, NSET={GRIP_REF_SET}",
        str(ref),
        "*BOUNDARY",
        f"{inp_name(roles.load)}, {across[0]}, {across[0]}",
        f"{inp_name(roles.load)}, {across[1]}, {across[1]}",
        "*EQUATION",
    ]
    for n in grip[1:].tolist():
        out += ["2", f"{n}, {dof}, 1.0, {ref}, {dof}, -1.0"]
    return out


def _springs(mesh: HexMesh, s: DeckSettings, roles: Roles, dof: int, first: int) -> list[str]:
    out: list[str] = []
    eid = first
    for part in roles.floating:
        nodes = mesh.part_nodes(part) + 1
        k = s.float_spring_n_per_mm / len(nodes)
        if s.float_spring_n_per_mm == 0.0:
            continue
        out += [
            "**",
            f"** ---- {part} is held only by contact: grounded springs on all {len(nodes)} nodes,",
            f"** {s.float_spring_n_per_mm:g} N/mm in total per direction, remove its rigid modes"
            " before contact closes. ----",
        ]
        for d in (1, 2, 3):
            elset = inp_name(f"spring_{part}_{'xyz'[d - 1]}")
            out += [f"*ELEMENT, TYPE=SPRING1, ELSET={elset}"]
            out += [f"{eid + i}, {n}" for i, n in enumerate(nodes.tolist())]
            eid += len(nodes)
            out += [f"*SPRING, ELSET={elset}", str(d), num(k)]
    if s.grip_spring > 0.0:
        ref = int(mesh.set_nodes(roles.load)[0]) + 1
        out += [
            "**",
            f"** ---- Grip spring {s.grip_spring:g} N/mm to ground: holds the grip across the free",
            f"** play 4 dr; at +-2 dr it takes {s.grip_spring * 2 * s.clearance_mm:g} N, added to"
            " the *CLOAD. ----",
            "*ELEMENT, TYPE=SPRING1, ELSET=spring_grip",
            f"{eid}, {ref}",
            "*SPRING, ELSET=spring_grip",
            str(dof),
            num(s.grip_spring),
        ]
    return out


def deck_text(
    mesh: HexMesh, faces: Mapping[str, NamedFace], settings: DeckSettings, *, title: str = ""
) -> str:
    """Return the input deck of a meshed hinge.

    Args:
        mesh: The mesh; its facet sets, pairs and parts name everything in the deck.
        faces: The model's named faces (``HingeModel.faces``): their roles say which sets
            are fixed (FIXED), loaded (LOAD, exactly one, a plane normal to x, y or z).
        settings: Load, friction and contact-law settings.
        title: The ``*HEADING`` line.

    Returns:
        The deck, one string ending in a newline.

    Raises:
        ParameterError: No FIXED set, not exactly one LOAD set, or a load face that is not
            an axis-aligned plane.
        MeshQualityError: A facet that is no element face, or two names that become one
            deck label.
    """
    labels = [inp_name(n) for n in (*mesh.part_names, *mesh.facet_sets, *mesh.node_sets)]
    dupes = sorted({x for x in labels if [y.upper() for y in labels].count(x.upper()) > 1})
    if dupes:
        raise MeshQualityError(f"names collide as deck labels (case-insensitive): {dupes}")
    roles = _roles(mesh, faces)
    dof, sign = _load_axis(faces[roles.load])
    lines = [
        *_header(mesh, settings, title),
        *_geometry(mesh),
        *_sets(mesh),
        *_materials(mesh),
        *_boundary(mesh, faces, roles),
        *_springs(mesh, settings, roles, dof, first=mesh.n_elem + 1),
        *_interactions(mesh, settings),
        *steps(settings, roles, sign, dof),
    ]
    return "\n".join(lines) + "\n"


def write_deck(
    mesh: HexMesh,
    faces: Mapping[str, NamedFace],
    settings: DeckSettings,
    path: Path,
    *,
    title: str = "",
) -> Path:
    """Write ``deck_text(mesh, faces, settings)`` to ``path`` (parents created); return it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(deck_text(mesh, faces, settings, title=title), encoding="utf-8")
    return path
