"""The candidate effects: each a mechanism with bounded parameters and a stated fingerprint.

Registered, in application order, in ``fe.effects.registry.REGISTRY``; the fingerprint tables in the
docstrings are measured as described in ``fe.effects``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fe.effects.base import (
    Effect,
    EffectContext,
    FloatArray,
    History,
    ParamSpec,
    Values,
    add_diagonal,
    map_configs,
)
from fe.general.faces import FOOTPRINT_RADIUS_RATIO, clamped_faces
from fe.structure.condensed import Condensed


@dataclass(frozen=True)
class FrameCompliance(Effect):
    """Series compliance of the test frame, load cell, grips and clevis pins.

    MECHANISM: the crosshead (or LVDT across the grips) measures the hinge in series with
    everything else in the load path; a linear spring ``C_f``: ``δ ← δ + C_f F``. It acts
    after the solve (``post``), so ``W`` and every factorisation are untouched.

    FINGERPRINT (C_f = 2e-5 mm/N): the loop is sheared — every point moves by
    ``C_f F``, the loop area W_cycle is unchanged (∮F d(C_f F) = 0), δ(+Fg) grows by
    exactly ``C_f Fg`` and ``η`` falls by ``δ_max / (δ_max + C_f Fg)``:

    =======  =====  =======  =========  ==========  ============
    Δr mm    Fg N   η base   η effect   δ+ base µm  δ+ effect µm
    =======  =====  =======  =========  ==========  ============
    0        100    0.01458  0.00418    0.98        2.98
    0        400    0.01458  0.00418    3.92        11.92
    0.1      100    0.00094  0.00042    2.00        4.00
    0.1      400    0.00126  0.00054    7.43        15.43
    =======  =====  =======  =========  ==========  ============

    η vs amplitude: at Δr = 0 the model stays homogeneous: η is independent of Fg, only
    lowered (×0.29 here). With Δr = 0.1 mm η falls by ×0.45 at 100 N and ×0.43 at 400 N,
    so the η(Fg) curve keeps its shape and is scaled down; the loop's area is unchanged.
    """

    name: str = "frame_compliance"
    params: tuple[ParamSpec, ...] = (
        ParamSpec(
            "compliance_mm_per_n", 0.0, 1e-4, 2e-5, "mm/N", "series compliance of frame and grips"
        ),
    )

    def post(self, history: History, values: Values) -> FloatArray:
        """Return ``δ + C_f F``, shape (n,) [mm]."""
        return history.disp_mm + values["compliance_mm_per_n"] * history.force_n


@dataclass(frozen=True)
class _InterfaceCompliance(Effect):
    """An interface compliance per unit area added to some local components of ``W``.

    ``W_kk,ii += c / A_i`` for every point i and each component k in ``components``
    (0 normal, 1 and 2 tangential); the parameter is ``compliance_mm3_per_n``.
    """

    components: tuple[int, ...] = ()

    def apply(
        self, configs: Mapping[int, Condensed], values: Values, ctx: EffectContext
    ) -> dict[int, Condensed]:
        """Add ``c / A_i`` to each point's diagonal entries of ``W`` in ``components``."""
        c = values["compliance_mm3_per_n"]
        if c == 0.0:
            return dict(configs)
        return map_configs(configs, lambda cond: add_diagonal(cond, self.components, c))


@dataclass(frozen=True)
class RoughnessSoftening(_InterfaceCompliance):
    """Contact softening by surface roughness: a linear pressure–overclosure law.

    MECHANISM: asperities of the turned pin and reamed holes deform before the nominal
    surfaces meet; to first order a normal interface stiffness per unit area ``k_n``
    (``p = k_n h`` for an overclosure h), i.e. a compliance ``c_n = 1/k_n`` [mm³/N] in
    series with the bulk at every contact point: ``W_nn,ii += c_n / A_i`` (A_i the
    slave nodal area). Only the diagonal normal entries change; no refactorisation. Linear,
    so the zero-clearance model stays positively homogeneous (an exponential law would
    break that, but needs the contact solver's normal law changed: not done).

    FINGERPRINT (c_n = 2e-4 mm³/N, i.e. k_n = 5000 N/mm³): a softer loop (δ(+Fg) ×1.7 at
    Δr = 0, ×2.2–2.7 at Δr = 0.1 mm) with a much larger area: the compliant layer lets
    the stick zones slip more, so η rises (×2.3 at Δr = 0, ×3.9–5.3 at Δr = 0.1 mm). The
    energy balance still closes to < 1e-12:

    =======  =====  =======  =========  ==========  ============
    Δr mm    Fg N   η base   η effect   δ+ base µm  δ+ effect µm
    =======  =====  =======  =========  ==========  ============
    0        100    0.01458  0.03426    0.98        1.65
    0        400    0.01458  0.03426    3.92        6.60
    0.1      100    0.00094  0.00365    2.00        5.35
    0.1      400    0.00126  0.00668    7.43        16.36
    =======  =====  =======  =========  ==========  ============

    η vs amplitude: flat at Δr = 0 (homogeneous, as the baseline); with clearance η still
    rises with Fg as in the baseline (0.0037 → 0.0067 for 0.00094 → 0.00126): the law is
    linear, so it raises the level, not the amplitude slope.
    """

    name: str = "roughness_softening"
    params: tuple[ParamSpec, ...] = (
        ParamSpec(
            "compliance_mm3_per_n",
            0.0,
            1e-3,
            2e-4,
            "mm³/N",
            "normal interface compliance per unit area, 1/k_n (k_n ≥ 1000 N/mm³)",
        ),
    )

    components: tuple[int, ...] = (0,)


@dataclass(frozen=True)
class TangentialCompliance(_InterfaceCompliance):
    """Shear compliance of the asperity layer (pre-sliding microslip of the asperities).

    MECHANISM: before the nominal surfaces slip, the asperity junctions shear elastically:
    a tangential interface stiffness per unit area ``k_t``, compliance ``c_t = 1/k_t``
    [mm³/N]: ``W_tt,ii += c_t / A_i`` in both tangential directions. No refactorisation.

    FINGERPRINT (c_t = 2e-4 mm³/N): the loop barely softens (δ(+Fg) +0.5–1 %) but
    thins: the compliant layer takes up the tangential motion elastically, the surfaces
    stick where they slipped, and η falls ×0.31 at Δr = 0; with Δr = 0.1 mm, where the
    contact arc is narrow, slip almost vanishes (η ≈ 0 at 100 N, 0.00004 at 400 N):

    =======  =====  =======  =========  ==========  ============
    Δr mm    Fg N   η base   η effect   δ+ base µm  δ+ effect µm
    =======  =====  =======  =========  ==========  ============
    0        100    0.01458  0.00446    0.98        0.98
    0        400    0.01458  0.00446    3.92        3.94
    0.1      100    0.00094  0.00000    2.00        2.02
    0.1      400    0.00126  0.00004    7.43        7.49
    =======  =====  =======  =========  ==========  ============

    η vs amplitude: flat at Δr = 0 (linear, homogeneous). With clearance η ≈ 0 at low Fg
    and rises only once the arc slips: a threshold in η(Fg), like a preload, but with an
    almost unchanged stiffness.
    """

    name: str = "tangential_compliance"
    params: tuple[ParamSpec, ...] = (
        ParamSpec(
            "compliance_mm3_per_n",
            0.0,
            1e-3,
            2e-4,
            "mm³/N",
            "tangential interface compliance per unit area, 1/k_t",
        ),
    )

    components: tuple[int, ...] = (1, 2)


@dataclass(frozen=True)
class Interference(Effect):
    """An initial radial pin–hole interference (a press or shrink fit, or a pin on the high side).

    MECHANISM: the pin is larger than the hole by ``δ_i`` (radial): the normal gap at every
    contact point starts at ``g0 − δ_i`` (``w0_n`` and ``geo.g0`` both shifted, so the seed
    of a touching configuration sees it too). The overlap is resolved in the first load
    increment from zero, which converges without a separate ramp (checked by the tests),
    as a radial prestress that clamps the pin before any load. With Δr > 0 the same
    overlap is applied in each touching configuration: it then stands for a local
    interference at the bearing line (out-of-roundness, burr), not a press fit.

    FINGERPRINT (δ_i = 1e-3 mm; δ measured from the prestressed zero δ₀ =
    0.84 δ_i, see ``fe.effects.cycle.prestressed_zero``): a stiffer loop (δ(+Fg) ×0.53 at 100 N, ×0.55 at
    400 N), almost closed at 100 N (the clamp keeps the contact stuck: η ×0.16) and wider
    than the baseline at 400 N (η ×1.44). The first loop after the initial loading does
    not quite close (1.1 % of δ_max at 400 N, 6 increments): the stick zones ratchet.
    Refused with clearance (an interference is a negative clearance):

    =======  =====  =======  =========  ==========  ============
    Δr mm    Fg N   η base   η effect   δ+ base µm  δ+ effect µm
    =======  =====  =======  =========  ==========  ============
    0        100    0.01458  0.00230    0.98        0.52
    0        400    0.01458  0.02104    3.92        2.17
    =======  =====  =======  =========  ==========  ============

    η vs amplitude: the clamp does not scale with Fg, so the model is no longer
    homogeneous: η rises steeply with Fg (0.0023 → 0.0210 from 100 to 400 N), the
    amplitude dependence the zero-clearance baseline lacks. η depends on Fg/δ_i only
    (both scale together); at δ_i = 1e-4 mm, 100 N already lies past the peak (η = 0.027, 6 increments).
    """

    name: str = "interference"
    params: tuple[ParamSpec, ...] = (
        ParamSpec("interference_mm", 0.0, 0.01, 1e-3, "mm", "initial radial pin–hole overlap"),
    )
    zero_clearance_reason: str = "an interference is a negative clearance"

    def apply(
        self, configs: Mapping[int, Condensed], values: Values, ctx: EffectContext
    ) -> dict[int, Condensed]:
        """Shift every point's initial normal gap by ``−δ_i``."""
        d = values["interference_mm"]
        if d == 0.0:
            return dict(configs)
        self.refuse_clearance(configs, "interference_mm", d)

        def change(cond: Condensed) -> Condensed:
            w0 = np.array(cond.w0, dtype=np.float64, copy=True)
            w0[:, 0] -= d
            geo = dataclasses.replace(cond.geo, g0=np.asarray(cond.geo.g0) - d)
            return dataclasses.replace(cond, geo=geo, w0=w0)

        return map_configs(configs, change)


@dataclass(frozen=True)
class FaceFriction(Effect):
    """Friction between the tang and clevis faces under the pin's axial clamp.

    MECHANISM: a bolt (or a pin with a nut or a swaged head) clamps the clevis arms onto
    the tang with a preload N per face. The faces then carry part of the load in
    parallel to the pin, by friction: while they stick the hinge is stiffer and loses
    less; once the load exceeds what they hold (about 2μN), they slip and add
    dissipation. Modelled as extra frictional contact points in the condensed problem
    (``fe.general.faces``): the tang's nodes on both faces inside a washer footprint
    (r ≤ ``FOOTPRINT_RADIUS_RATIO`` × hole radius), each against the arm's inner face
    (``n = ∓e_z``), the same Coulomb μ as the pin, coupled to the hole points through
    the lugs' compliance. Their initial normal displacement is an overlap
    ``w0_n = −δ_c`` (the 0.2 mm running gap ignored over the footprint, as if shimmed),
    with δ_c set so that the face normal forces at F = 0 sum to ``clamp_force_n`` on each
    face (``clamped_faces``: one unloaded solve with the cycle's μ; the problem is
    homogeneous, so the conversion is exact). The bolt is not a body: the clamp is held
    by the arms' spread instead of the bolt's stretch, so how the face force varies
    during the cycle follows the arms' stiffness, not a bolt's. At F = 0 the clamp also
    presses the holes onto the pin a little (40 N summed over the pin points at 300 N).
    The clamp is applied with the first load increment (the cycle has no separate
    preload stage); the prestressed zero δ₀ (``fe.effects.cycle.prestressed_zero``)
    is the zero of the loop. The energy balance (friction work at pin and face points
    against the loop area) still closes to round-off. With clamp 0 the faces stay apart
    (the baseline exactly).

    FINGERPRINT (N = 300 N per face, δ measured from the prestressed zero δ₀): a stiffer
    loop (δ(+Fg) ×0.70 at 100 N, ×0.76 at 400 N: the faces hold μN = 60 N each before
    slipping), with less loss at low Fg once shaken down and more at high Fg, where
    the faces slip (each face dissipates about 4μN·s per cycle for a slip amplitude s).
    The first loop after the initial loading does not close at 100 N (−14 % of δ_max
    at 40 increments, −4 % at 400 N): the tractions the clamp locks into the faces
    (the tang's Poisson expansion resisted by friction) shake down during that cycle,
    so its area is 4× the settled one. The table is that first loop (the protocol's
    ``n_cycles = 1``); with ``n_cycles = 2`` the loop closes (0.3 %) and η is 0.0083 at
    100 N and 0.0575 at 400 N (40 increments). Applying the clamp before the load
    instead of with the first increment changes η by < 5 % (6 increments, measured):

    =======  =====  =======  =========  ==========  ============
    Δr mm    Fg N   η base   η effect   δ+ base µm  δ+ effect µm
    =======  =====  =======  =========  ==========  ============
    0        100    0.01458  0.03164    0.98        0.68
    0        400    0.01458  0.06059    3.92        2.99
    0.1      100    0.00094  0.06214    2.00        1.34
    0.1      400    0.00126  0.37625    7.43        189.63
    =======  =====  =======  =========  ==========  ============

    η vs amplitude: the clamp does not scale with Fg, so the model is no longer
    homogeneous: η rises with Fg (0.032 → 0.061 from 100 to 400 N; shaken down
    0.0083 → 0.0575, below the baseline's 0.0146 at 100 N and 4× above it at 400 N) and
    the secant stiffness falls (the faces' share of the load saturates at 2μN).
    With μ = 0 the faces carry no load in parallel and there is no loop: η = 0.0006 at
    6 increments, 0.00002 at 40, the open/close work of points whose status changes
    inside an increment (first order in the step; the baseline has none, its active set
    is fixed along each half cycle).

    With clearance (``fe.general.freeplay``): the clamp is set with the pin centred,
    touching nothing (the faces alone; the arms then bend more freely than around a
    tight pin: overlap 61 µm instead of 24 µm for 300 N on the coarse mesh), and the
    cycle starts centred. The faces hold the clevis wherever it is in the free play
    until the force reaches their slip force ``F_slide = μ Σ p_n`` (measured
    116.27 N pulling, 123.85 N pushing at N = 300 N, μ = 0.2, against 2μN = 120 N:
    the friction tractions bend the arms and change the face pressure, by ±3 % with
    opposite signs in the two directions, the clevis being attached on one side
    only); then the clevis slides rigidly across the free play at that force until
    the pin touches the other side. The travel between the two touching
    configurations is 4Δr (the clevis at ±2Δr from the tang, ``configurations``);
    the slide measured 378.5 µm at Δr = 0.1 mm (4Δr less 21 µm: the clamp-bent arms
    move where the pin first touches). The slide is a rectangle of area
    ``F_slide × travel`` in the loop, real dissipation at the faces, so with clearance
    η is reported on the loop the grips follow, free play included (δ_max too, the
    rectangle being most of W: 91 of 94 N·mm at Δr = 0.1 mm, 400 N); the energy
    balance closes to 3e-16. Below F_slide (100 N here) the clevis never leaves the
    centre, the pin is never touched and the loop is the faces' own. Measured, coarse
    mesh, 40 increments, ``n_cycles = 1`` (2: the loop shaken down):

    ======  =====  =======  =================  ============  ====================
    Δr mm   Fg N   η base   η effect (n = 2)   δ+ base µm    crossing
    ======  =====  =======  =================  ============  ====================
    0.1     100    0.00094  0.0621 (0.0470)    2.00          none (faces hold)
    0.1     400    0.00126  0.3762 (0.3762)    7.43          ±F_slide, 378.5 µm
    0.2     100    0.00095  0.0628 (0.0474)    2.03          none (faces hold)
    0.2     400    0.00097  0.3792 (0.3792)    8.11          ±F_slide, 778.6 µm
    ======  =====  =======  =================  ============  ====================

    Above F_slide η ≈ 4 F_slide / (π Fg) whatever Δr (W ≈ 2 F_slide · 4Δr,
    U_max ≈ ½ Fg · 2Δr): 0.38 at 400 N. With μ = 0 the slides carry no force and
    there is no rectangle; with clamp 0 the cycle is the clearance baseline bit for
    bit (the same code path). The approximation: the face points keep their master
    facets over the 4Δr slide (small sliding on the arm's plane).
    """

    name: str = "face_friction"
    params: tuple[ParamSpec, ...] = (
        ParamSpec(
            "clamp_force_n",
            0.0,
            2000.0,
            300.0,
            "N",
            "axial clamp (bolt preload) pressing each clevis arm onto the tang",
        ),
    )

    def apply(
        self, configs: Mapping[int, Condensed], values: Values, ctx: EffectContext
    ) -> dict[int, Condensed]:
        """Append the clamped face points to the (single) configuration."""
        clamp = values["clamp_force_n"]
        if clamp == 0.0:
            return dict(configs)
        centred = configs.get(1) is not configs.get(-1)  # clearance: two configurations
        return map_configs(
            configs,
            lambda cond: (
                clamped_faces(
                    ctx.system, cond, clamp, ctx.contact(), FOOTPRINT_RADIUS_RATIO, centred
                ).cond
            ),
        )
