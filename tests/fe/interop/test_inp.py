"""The ABAQUS/CalculiX deck: parsed back by an independent reader, it is the mesh and model.

The reader here is deliberately separate from ``fe.interop``: it splits the deck into
keyword cards and checks what a solver would see (node numbers, connectivity, set sizes,
loads, references). If CalculiX is installed, a cube pulled by the exporter's own
primitives is compared with F L / (E A).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cad.errors import DataError, MeshQualityError, ParameterError
from cad.materials import Material
from cad.model import FaceRole, NamedFace, PairKind, SurfacePair
from cad.surfaces import Cylinder, Plane
from fe.interop.ccx import (
    StaSummary,
    find_ccx,
    loop_figures,
    loop_from_dat,
    parse_dat,
    parse_sta,
    run_ccx,
)
from fe.interop.deck_settings import (
    CYCLE,
    EXACT_STICK_SLOPE_MPA_PER_MM,
    SETTLE_INCREMENT_N,
    TOUCH_INCREMENT_N,
    ContactType,
    DeckSettings,
)
from fe.interop.inp import C3D8_FACES, deck_text, facet_element_faces, write_deck
from fe.interop.inp_names import GRIP_REF_SET, inp_name
from tests.helpers import box_mesh, merge_meshes

# -- an independent reader ------------------------------------------------------------


@dataclasses.dataclass
class Card:
    keyword: str
    params: dict[str, str]
    data: list[list[str]]


def parse_cards(text):
    cards = []
    for line in text.splitlines():
        if line.startswith("**") or not line.strip():
            continue
        if line.startswith("*"):
            head, *rest = (x.strip() for x in line[1:].split(","))
            params = {}
            for r in rest:
                k, _, v = r.partition("=")
                params[k.strip().upper()] = v.strip()
            cards.append(Card(head.upper(), params, []))
        else:
            cards[-1].data.append([x.strip() for x in line.split(",") if x.strip()])
    return cards


def cards_of(cards, keyword):
    return [c for c in cards if c.keyword == keyword]


def ints(card):
    return [int(x) for row in card.data for x in row]


# -- fixtures -------------------------------------------------------------------------


def grip_faces(length):
    return {
        "xmin": NamedFace("xmin", "block", FaceRole.FIXED, Plane((0, 0, 0), (-1, 0, 0))),
        "xmax": NamedFace("xmax", "block", FaceRole.LOAD, Plane((length, 0, 0), (1, 0, 0))),
    }


@pytest.fixture(scope="module")
def hinge():
    from cad.general import make_general_hinge
    from cad.general_params import GeneralHingeParams
    from mesh.build import mesh_hinge
    from mesh.settings import MeshSettings

    model = make_general_hinge(GeneralHingeParams(clearance_mm=0.1))
    mesh, _ = mesh_hinge(model, MeshSettings.coarse())
    return model, mesh


@pytest.fixture(scope="module")
def hinge_deck(hinge):
    model, mesh = hinge
    settings = DeckSettings(amplitude_n=400.0, mu=0.2, clearance_mm=0.1)
    return settings, parse_cards(deck_text(mesh, model.faces, settings))


# -- the hinge deck -------------------------------------------------------------------


def test_nodes_are_ours_plus_one(hinge, hinge_deck):
    _, mesh = hinge
    (card,) = cards_of(hinge_deck[1], "NODE")
    ids = np.array([int(r[0]) for r in card.data])
    xyz = np.array([[float(v) for v in r[1:]] for r in card.data])
    assert np.array_equal(ids, np.arange(1, mesh.n_nodes + 1))
    assert np.allclose(xyz, mesh.nodes, rtol=1e-12, atol=1e-12)


def test_elements_per_part_are_our_connectivity(hinge, hinge_deck):
    _, mesh = hinge
    solid = [c for c in cards_of(hinge_deck[1], "ELEMENT") if c.params["TYPE"] == "C3D8I"]
    assert [c.params["ELSET"] for c in solid] == [inp_name(p) for p in mesh.part_names]
    for card, part in zip(solid, mesh.part_names, strict=True):
        rows = np.array([[int(x) for x in r] for r in card.data])
        assert np.array_equal(rows[:, 0] - 1, mesh.part_elements(part))
        assert np.array_equal(rows[:, 1:] - 1, mesh.hexes[mesh.part_elements(part)])


C3D8_REFERENCE = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ],
    dtype=np.float64,
)
"""C3D8's reference node coordinates (ABAQUS manual), transcribed here, not taken from our
element code: the tests check our connectivity against them."""


def test_c3d8_node_order_gives_positive_volume(hinge):
    """C3D8's reference node coordinates (ABAQUS manual) at the connectivity we write."""
    _, mesh = hinge
    c3d8_ref = C3D8_REFERENCE
    dN = c3d8_ref / 8.0  # trilinear shape-function gradients at the centre, (8, 3)
    J = np.einsum("eni,nj->eij", mesh.nodes[mesh.hexes], dN)  # (n_elem, 3, 3)
    assert np.all(np.linalg.det(J) > 0.0)


def test_c3d8_faces_are_the_outer_faces_of_the_reference_hex():
    ref = C3D8_REFERENCE
    # S1 … S6 lie on ζ = −1, ζ = +1, η = −1, ξ = +1, η = +1, ξ = −1 (ABAQUS numbering).
    expected = [(2, -1), (2, 1), (1, -1), (0, 1), (1, 1), (0, -1)]
    for face, (axis, side) in zip(C3D8_FACES, expected, strict=True):
        assert np.all(ref[list(face), axis] == side)


def test_surfaces_and_node_sets_are_our_facet_sets(hinge, hinge_deck):
    _, mesh = hinge
    cards = hinge_deck[1]
    hexes = mesh.hexes
    surfaces = {c.params["NAME"]: c for c in cards_of(cards, "SURFACE")}
    nsets = {c.params["NSET"]: c for c in cards_of(cards, "NSET")}
    for name, facets in mesh.facet_sets.items():
        faces = set()
        for elem, s in surfaces[inp_name(name)].data:
            local = C3D8_FACES[int(s[1:]) - 1]
            faces.add(tuple(sorted(hexes[int(elem) - 1, list(local)])))
        assert faces == {tuple(sorted(f)) for f in facets.tolist()}, name
        assert sorted(np.array(ints(nsets[inp_name(name)])) - 1) == mesh.set_nodes(name).tolist()


def test_each_step_applies_plus_minus_fg_through_the_hinge(hinge_deck):
    settings, cards = hinge_deck
    steps = cards_of(cards, "CLOAD")
    assert len(steps) == len(CYCLE) == len(cards_of(cards, "STEP"))
    (grip,) = cards_of(cards, "SPRING")[-1:]
    k_grip = float(grip.data[1][0])
    for card, factor in zip(steps, CYCLE, strict=True):
        ((node_set, dof, value),) = card.data
        assert (node_set, dof) == (GRIP_REF_SET, "1")
        # The grip spring takes k·2Δr at the touching configuration; the rest is the hinge's.
        through_hinge = float(value) - np.sign(factor) * k_grip * 2 * settings.clearance_mm
        assert through_hinge == pytest.approx(factor * settings.amplitude_n, rel=1e-12)


def test_grip_moves_rigidly_along_x(hinge, hinge_deck):
    _, mesh = hinge
    cards = hinge_deck[1]
    grip = mesh.set_nodes("clevis_load") + 1
    (ref,) = ints(next(c for c in cards_of(cards, "NSET") if c.params["NSET"] == GRIP_REF_SET))
    eqs = [row for c in cards_of(cards, "EQUATION") for row in c.data if len(row) == 6]
    assert {int(r[0]) for r in eqs} | {ref} == set(grip.tolist())
    assert all(r[1] == "1" and int(r[3]) == ref and float(r[2]) == -float(r[5]) for r in eqs)


def test_every_referenced_set_is_defined(hinge_deck):
    cards = hinge_deck[1]
    nsets = {
        c.params["NSET"] for c in cards if "NSET" in c.params and c.keyword in ("NSET", "NODE")
    }
    elsets = {c.params["ELSET"] for c in cards if c.keyword == "ELEMENT"}
    surfaces = {c.params["NAME"] for c in cards_of(cards, "SURFACE")}
    interactions = {c.params["NAME"] for c in cards_of(cards, "SURFACE INTERACTION")}
    materials = {c.params["NAME"] for c in cards_of(cards, "MATERIAL")}
    for c in cards:
        if c.keyword in ("BOUNDARY", "CLOAD"):
            assert {r[0] for r in c.data if not r[0].isdigit()} <= nsets, c
        if c.keyword in ("NODE PRINT",):
            assert c.params["NSET"] in nsets
        if c.keyword in ("SOLID SECTION", "SPRING"):
            assert c.params["ELSET"] in elsets
        if c.keyword == "SOLID SECTION":
            assert c.params["MATERIAL"] in materials
        if c.keyword == "CONTACT PAIR":
            assert c.params["INTERACTION"] in interactions
            assert {x for r in c.data for x in r} <= surfaces


def test_contact_pairs_slave_is_the_pin(hinge, hinge_deck):
    model, mesh = hinge
    pairs = [r for c in cards_of(hinge_deck[1], "CONTACT PAIR") for r in c.data]
    assert [(s, m) for s, m in pairs] == [
        (inp_name(p.slave), inp_name(p.master)) for p in mesh.pairs
    ]
    assert all(model.faces[p.slave].part == "pin" for p in mesh.pairs)
    frictions = cards_of(hinge_deck[1], "FRICTION")
    assert len(frictions) == len(mesh.pairs)
    assert all(float(c.data[0][0]) == 0.2 for c in frictions)


def test_pin_gets_weak_springs_in_three_directions(hinge, hinge_deck):
    _, mesh = hinge
    springs = [c for c in cards_of(hinge_deck[1], "ELEMENT") if c.params["TYPE"] == "SPRING1"]
    pin = [c for c in springs if c.params["ELSET"].startswith("spring_pin")]
    assert len(pin) == 3
    for c in pin:
        assert sorted(int(r[1]) - 1 for r in c.data) == mesh.part_nodes("pin").tolist()
    totals = [
        float(c.data[1][0]) * mesh.part_nodes("pin").size
        for c in cards_of(hinge_deck[1], "SPRING")[:3]
    ]
    assert totals == pytest.approx([1.0] * 3)


def test_every_field_fits_ccx_twenty_characters(hinge, hinge_deck):
    model, mesh = hinge
    text = deck_text(mesh, model.faces, DeckSettings(clearance_mm=0.1))
    long = [f for line in text.splitlines() if not line.startswith("*") for f in line.split(",")]
    assert max(len(f.strip()) for f in long) <= 20


def test_surface_to_surface_has_one_value_law(hinge):
    model, mesh = hinge
    cards = parse_cards(
        deck_text(mesh, model.faces, DeckSettings(contact=ContactType.SURFACE_TO_SURFACE, mu=0.0))
    )
    laws = [c for c in cards if c.keyword == "SURFACE BEHAVIOR"]
    assert all(len(c.data[0]) == 1 for c in laws)
    assert not cards_of(cards, "FRICTION")
    assert all(c.params["TYPE"] == "SURFACE TO SURFACE" for c in cards_of(cards, "CONTACT PAIR"))


# -- small meshes, errors -------------------------------------------------------------


def test_bonded_pair_becomes_a_tie():
    a = box_mesh(2.0, 1.0, 1.0, 2, 1, 1, part="a", set_prefix="a_")
    b = box_mesh(2.0, 1.0, 1.0, 2, 1, 1, origin=(2.0, 0.0, 0.0), part="b", set_prefix="b_")
    m = merge_meshes(a, b)
    m = dataclasses.replace(m, pairs=(SurfacePair("glue", "b_xmin", "a_xmax", PairKind.BONDED),))
    faces = {
        "a_xmin": NamedFace("a_xmin", "a", FaceRole.FIXED, Plane((0, 0, 0), (-1, 0, 0))),
        "b_xmax": NamedFace("b_xmax", "b", FaceRole.LOAD, Plane((4, 0, 0), (1, 0, 0))),
    }
    cards = parse_cards(deck_text(m, faces, DeckSettings()))
    (tie,) = cards_of(cards, "TIE")
    assert tie.data == [["b_xmin", "a_xmax"]]
    assert not cards_of(cards, "CONTACT PAIR")
    assert not [c for c in cards_of(cards, "ELEMENT") if c.params["TYPE"] == "SPRING1"]


def test_facet_lookup_finds_element_and_face():
    m = box_mesh(3.0, 1.0, 1.0, 3, 1, 1)
    elem, face = facet_element_faces(m, m.facet_sets["xmax"])
    assert elem.tolist() == [2]
    assert face.tolist() == [4]  # S4: xi = +1
    with pytest.raises(MeshQualityError, match="no element face"):
        facet_element_faces(m, np.array([[0, 1, 2, 3]], dtype=np.int64))


@pytest.mark.parametrize(
    ("field", "value"),
    [("mu", -0.1), ("amplitude_n", 0.0), ("penalty_mpa_per_mm", -1.0), ("clearance_mm", 11.0)],
    ids=["mu", "amplitude", "penalty", "clearance"],
)
def test_bad_setting_names_itself(field, value):
    with pytest.raises(ParameterError, match=rf"^{field} must be in .* got {value!r}$"):
        DeckSettings(**{field: value})


def test_model_without_load_face_is_refused():
    m = box_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    faces = {"xmin": grip_faces(1.0)["xmin"]}
    with pytest.raises(ParameterError, match="exactly one LOAD"):
        deck_text(m, faces, DeckSettings())


def test_oblique_load_face_is_refused():
    m = box_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    faces = grip_faces(1.0) | {
        "xmax": NamedFace("xmax", "block", FaceRole.LOAD, Plane((1, 0, 0), (1, 1, 0)))
    }
    with pytest.raises(ParameterError, match="normal must lie along x, y or z"):
        deck_text(m, faces, DeckSettings())
    faces["xmax"] = NamedFace(
        "xmax", "block", FaceRole.LOAD, Cylinder((0, 0, 0), (0, 0, 1), 1.0, False)
    )
    with pytest.raises(ParameterError, match="must be a plane"):
        deck_text(m, faces, DeckSettings())


def test_names_become_labels():
    assert inp_name("pin-tang") == "pin_tang"
    assert inp_name("45 steel") == "N_45_steel"
    with pytest.raises(ParameterError, match="must not be empty"):
        inp_name("")


def test_colliding_labels_are_refused():
    m = box_mesh(1.0, 1.0, 1.0, 1, 1, 1, set_prefix="a-")
    m = dataclasses.replace(m, facet_sets={**m.facet_sets, "a_xmin": m.facet_sets["a-xmin"]})
    faces = {k.replace("x", "a-x", 1): v for k, v in grip_faces(1.0).items()}
    with pytest.raises(MeshQualityError, match="collide"):
        deck_text(m, faces, DeckSettings())


# -- a cube in CalculiX ---------------------------------------------------------------


def test_ccx_bar_matches_closed_form(tmp_path):
    """A 4 × 1 × 1 mm bar (ν = 0, so the clamped ends do not matter): δ = F L / (E A)."""
    if find_ccx() is None:
        pytest.skip("CalculiX (ccx) is not installed: run `make peers` (needs root) to install it")
    E, F, L = 70_000.0, 100.0, 4.0
    m = box_mesh(L, 1.0, 1.0, 4, 1, 1, material=Material("nu0", E, 0.0))
    deck = write_deck(m, grip_faces(L), DeckSettings(amplitude_n=F, mu=0.0), tmp_path / "bar.inp")
    run = run_ccx(deck, timeout_s=20.0)
    loop = loop_from_dat(parse_dat(run.dat), GRIP_REF_SET, ["xmin"])
    assert loop.step.tolist() == [1, 1, 2, 3]
    assert loop.hinge_force_n.tolist() == pytest.approx([0.0, F, -F, F], abs=1e-9)
    # The .dat file prints 7 significant digits.
    assert loop.grip_disp_mm == pytest.approx(loop.hinge_force_n * L / E, rel=1e-6, abs=1e-15)
    fig = loop_figures(loop.hinge_force_n, loop.grip_disp_mm, loop.step, F)
    assert fig.area_nmm == pytest.approx(0.0, abs=1e-12)


def test_loop_figures_remove_the_free_play_from_every_point():
    """A force left at the end of a free-play crossing counts only over what is left of it.

    A hinge of compliance 1/k with a friction loop of width 2c (down branch δ = F/k + c, up
    branch δ = F/k − c: area 4 c Fg), seen at the grip through a free play of 4Δr crossed at
    F = 0 in one increment that ends 10 µm before the touch with 0.2 N, which then falls to
    zero as the pin closes those 10 µm (as ccx on the 2 mm mesh). Removing half the free play
    from every point leaves that force 10 µm to act over; on the raw points the trapezoid
    across the 0.39 mm crossing was 0.039 N·mm, twice this loop.
    """
    k, c, fg, half = 4e4, 1e-5, 400.0, 0.2  # N/mm, mm, N, 2Δr [mm]
    up_f = np.linspace(0.0, fg, 21)
    f = [0.0, *up_f[1:]]  # stage 1: first loading, + side
    x = [0.0, *(up_f[1:] / k + half)]
    st = [1] * len(f)
    for stage, sign in ((2, -1.0), (3, 1.0)):
        branch = c if stage == 2 else -c  # down: +c, up: -c
        ff = sign * np.concatenate([-up_f[::-1], up_f[1:]])  # the other peak to this one
        for j, F in enumerate(ff):
            if j == len(up_f) - 1:  # F = 0: the crossing, ending 10 µm short with 0.2 N
                f += [0.0, sign * 0.2, sign * 0.1, 0.0]
                x += [-sign * half + branch, *(sign * (half - g) for g in (0.01, 0.005, 0.0))]
                st += [stage] * 4
                continue
            f.append(F)
            x.append(F / k + branch + np.sign(F) * half)
            st.append(stage)
    fig = loop_figures(np.array(f), np.array(x), np.array(st), fg, free_play_mm=2 * half)
    assert fig.area_nmm == pytest.approx(4 * c * fg, abs=2 * 0.2 * 0.01)  # ±0.25 of it
    assert fig.disp_at_plus_mm == pytest.approx(fg / k - c)
    assert fig.disp_at_minus_mm == pytest.approx(-fg / k + c)


def test_dat_reader_names_a_bad_line(tmp_path):
    dat = tmp_path / "x.dat"
    dat.write_text(" displacements (vx,vy,vz) for set A and time  0.1E+01\n\n 1 2.0 x 3\n")
    with pytest.raises(Exception, match=r"x.dat:3: expected numbers"):
        parse_dat(dat)


def test_dat_reader_reads_three_digit_exponents(tmp_path):
    """ccx writes |x| < 1e-99 in Fortran's E13.6 without the ``E`` (seen in a real run)."""
    dat = tmp_path / "t.dat"
    dat.write_text(
        " displacements (vx,vy,vz) for set A and time  0.1E+01\n\n"
        "       12 -5.260560-144  2.814323-143  1.0E+00\n"
    )
    (block,) = parse_dat(dat)
    assert block.rows.tolist() == [[12.0, -5.260560e-144, 2.814323e-143, 1.0]]
    bad = tmp_path / "b.dat"
    bad.write_text(" displacements (vx,vy,vz) for set A and time  0.1E+01\n\n 1 2.0-1x4\n")
    with pytest.raises(Exception, match=r"b.dat:3: expected numbers"):
        parse_dat(bad)


def test_dat_reader_pairs_increments(tmp_path):
    dat = tmp_path / "a.dat"
    dat.write_text(
        " displacements (vx,vy,vz) for set GRIP_REF and time  0.5000000E+00\n\n"
        "        7  1.0E-03  0.0E+00  0.0E+00\n\n"
        " total force (fx,fy,fz) for set FIX and time  0.5000000E+00\n\n"
        "       -2.0E+02  0.0E+00  0.0E+00\n"
    )
    loop = loop_from_dat(parse_dat(dat), "grip_ref", ["fix"])
    assert loop.grip_disp_mm.tolist() == [0.0, 1e-3]
    assert loop.hinge_force_n.tolist() == [0.0, 200.0]
    assert loop.step.tolist() == [1, 1]


# -- mortar: hard contact, exact stick, tight tolerances -------------------------------


def test_exact_mortar_deck_has_no_penalty(hinge):
    model, mesh = hinge
    settings = DeckSettings.exact_mortar(clearance_mm=0.1)
    cards = parse_cards(deck_text(mesh, model.faces, settings))
    assert not cards_of(cards, "SURFACE BEHAVIOR")  # ccx's mortar: hard contact
    pairs = cards_of(cards, "CONTACT PAIR")
    assert len(pairs) == len(mesh.pairs)
    assert all(c.params["TYPE"] == "MORTAR" and "ADJUST" not in c.params for c in pairs)
    frictions = cards_of(cards, "FRICTION")
    assert [float(c.data[0][1]) for c in frictions] == [EXACT_STICK_SLOPE_MPA_PER_MM] * 3
    fields = [c for c in cards_of(cards, "CONTROLS") if c.params["PARAMETERS"] == "FIELD"]
    assert len(fields) == len(cards_of(cards, "STEP"))  # every step, touch bands included
    assert all(c.data == [["0.0001", "0.0001", "0.0001"]] for c in fields)
    times = [c for c in cards_of(cards, "CONTROLS") if c.params["PARAMETERS"] != "FIELD"]
    assert all(c.data[0][2] == c.data[0][3] == "50" for c in times)  # never the looser R_p


def _stages(cards, settings, initial=None):
    """Per step: (step time, largest increment, *CLOAD at its end as a load factor).

    ``initial`` (a list) receives each step's initial increment.
    """
    out = []
    for st, cl in zip(cards_of(cards, "STATIC"), cards_of(cards, "CLOAD"), strict=True):
        dt0, period, _, dt_max = (float(x) for x in st.data[0])
        if initial is None:
            assert dt0 == dt_max
        else:
            initial.append(dt0)
        out.append((period, dt_max, float(cl.data[0][2]) / settings.peak_cload_n))
    return out


def test_touch_bands_split_each_reversal_into_five_steps(hinge):
    """With clearance the mortar deck refines the load where the pin leaves and touches."""
    model, mesh = hinge
    settings = DeckSettings.exact_mortar(clearance_mm=0.1, amplitude_n=400.0)
    assert settings.touch_increment_n == TOUCH_INCREMENT_N
    assert settings.settle_increment_n == SETTLE_INCREMENT_N
    first: list[float] = []
    steps = _stages(parse_cards(deck_text(mesh, model.faces, settings)), settings, first)
    assert len(steps) == 1 + 5 * (len(CYCLE) - 1)
    assert steps[0] == pytest.approx((1.0, 2.0 / settings.increments_per_stage, CYCLE[0]))
    peak, band = settings.peak_cload_n, settings.touch_band_n
    spring = settings.grip_spring * 2 * settings.clearance_mm  # 10 N: the spring alone
    assert spring == pytest.approx(10.0)
    for k in range(1, len(CYCLE)):
        segs = steps[5 * k - 4 : 5 * k + 1]
        # the step times of a stage add up to 1: the total time still counts stages
        assert sum(s[0] for s in segs) == pytest.approx(1.0, abs=1e-12)
        d = np.sign(CYCLE[k] - CYCLE[k - 1])
        ends = [s[2] * peak for s in segs]
        leave, touch = -d * spring, d * spring
        assert ends[:4] == pytest.approx(
            [leave - d * band, leave + d * band, touch - d * band, touch + d * band]
        )
        assert segs[-1][2] == CYCLE[k]
        # the bands' increments, in newtons of *CLOAD; coarse elsewhere
        span_n = abs(CYCLE[k] - CYCLE[k - 1]) * peak
        assert segs[1][1] * span_n == pytest.approx(TOUCH_INCREMENT_N)
        assert segs[3][1] * span_n == pytest.approx(TOUCH_INCREMENT_N)
        assert segs[0][1] == segs[4][1] == pytest.approx(1.0 / settings.increments_per_stage)
        # after the touch band ccx starts small (SETTLE_INCREMENT_N) and grows; elsewhere
        # every step starts at its largest increment
        starts = first[5 * k - 4 : 5 * k + 1]
        assert starts[4] * span_n == pytest.approx(SETTLE_INCREMENT_N)
        assert starts[:4] == [s[1] for s in segs[:4]]
    assert first[0] == steps[0][1]


def test_touch_band_needs_free_play():
    assert DeckSettings.exact_mortar().touch_increment_n is None
    with pytest.raises(ParameterError, match=r"touch_increment_n = 0.01 N needs free play"):
        DeckSettings(touch_increment_n=0.01)
    with pytest.raises(ParameterError, match=r"touch_band_n = 10 N must be below"):
        DeckSettings(clearance_mm=0.1, touch_increment_n=0.01, touch_band_n=10.0)
    with pytest.raises(ParameterError, match=r"touch_increment_n"):
        DeckSettings(clearance_mm=0.1, touch_increment_n=-1.0)
    with pytest.raises(ParameterError, match=r"settle_increment_n = 0.3 N needs touch_incr"):
        DeckSettings(clearance_mm=0.1, settle_increment_n=0.3)
    with pytest.raises(ParameterError, match=r"settle_increment_n"):
        DeckSettings(clearance_mm=0.1, touch_increment_n=0.01, settle_increment_n=0.0)
    assert DeckSettings.exact_mortar().settle_increment_n is None


def test_without_settle_increment_every_step_starts_at_its_largest(hinge):
    model, mesh = hinge
    settings = DeckSettings.exact_mortar(clearance_mm=0.1, settle_increment_n=None)
    first: list[float] = []
    steps = _stages(parse_cards(deck_text(mesh, model.faces, settings)), settings, first)
    assert first == [s[1] for s in steps]


def test_default_deck_keeps_ccx_tolerances(hinge_deck):
    controls = cards_of(hinge_deck[1], "CONTROLS")
    assert {c.params["PARAMETERS"] for c in controls} == {"TIME INCREMENTATION"}
    assert all("ADJUST" in c.params for c in cards_of(hinge_deck[1], "CONTACT PAIR"))


@pytest.mark.parametrize(
    "field", ["penalty_mpa_per_mm", "stick_slope_mpa_per_mm"], ids=["hard", "exact_stick"]
)
@pytest.mark.parametrize(
    "contact",
    [ContactType.NODE_TO_SURFACE, ContactType.SURFACE_TO_SURFACE],
    ids=["node", "surface"],
)
def test_penalty_contact_refuses_exact_laws(field, contact):
    with pytest.raises(ParameterError, match=rf"^{field} must be a number for"):
        DeckSettings(contact=contact, **{field: None})


def test_mortar_with_penalty_and_stick_slope_writes_both(hinge):
    model, mesh = hinge
    settings = DeckSettings(contact=ContactType.MORTAR, penalty_mpa_per_mm=1e7)
    cards = parse_cards(deck_text(mesh, model.faces, settings))
    assert all(c.data == [["10000000."]] for c in cards_of(cards, "SURFACE BEHAVIOR"))
    assert all(c.data == [["0.2", "1000000."]] for c in cards_of(cards, "FRICTION"))


def test_sta_reader_counts_attempts(tmp_path):
    sta = tmp_path / "a.sta"
    sta.write_text(
        "SUMMARY OF JOB INFORMATION\n"
        "  STEP      INC     ATT  ITRS     TOT TIME     STEP TIME      INC TIME\n"
        "     1          1     1U    8  0.000000E+00  0.000000E+00  0.100000E+00\n"
        "     1          1     2     5  0.250000E-01  0.250000E-01  0.250000E-01\n"
        "     2          1     1     3  0.105000E+01  0.500000E-01  0.500000E-01\n"
    )
    assert parse_sta(sta) == StaSummary(increments=2, iterations=16, cutbacks=1, last_time=1.05)
    with pytest.raises(DataError, match=r"no such \.sta"):
        parse_sta(tmp_path / "missing.sta")


def test_conforming_mesh_starts_without_overclosure():
    """The cross-check's mesh: every pin contact node is a hole node at Δr = 0.

    With uniform arcs and one contact size on both sides (``slave_ratio`` 1), pin and hole
    facets are the same chords, so ccx's faceted surfaces touch without overclosure and
    the deck needs no ADJUST (tests/fe/interop/test_ccx_crosscheck.py).
    """
    from cad.general import make_general_hinge
    from cad.general_params import GeneralHingeParams
    from mesh.build import mesh_hinge
    from mesh.settings import MeshSettings

    model = make_general_hinge(GeneralHingeParams(clearance_mm=0.0))
    mesh, _ = mesh_hinge(model, MeshSettings.coarse(slave_ratio=1.0, arc_grading=1.0))
    for pair in mesh.pairs:
        pin = mesh.nodes[mesh.set_nodes(pair.slave)]
        hole = mesh.nodes[mesh.set_nodes(pair.master)]
        dist = np.linalg.norm(pin[:, None, :] - hole[None, :, :], axis=2).min(axis=1)
        assert dist.max() < 1e-9, pair.name
        assert len(pin) == len(hole), pair.name
