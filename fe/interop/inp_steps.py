"""The load history of a deck: 0 → +Fg → −Fg → +Fg as ccx ``*STEP`` blocks.

Each stage is one static step ramping the grip's ``*CLOAD`` (or five, where
``DeckSettings.touch_increment_n`` refines the bands where the pin leaves one side of the
free play and touches the other), with its ``*CONTROLS`` and the ``.dat`` output that
``fe.interop.ccx`` reads (see :mod:`fe.interop.inp`).
"""

from __future__ import annotations

from fe.interop.deck_settings import DeckSettings
from fe.interop.inp_names import GRIP_REF_SET, Roles, inp_name, num


def _controls(s: DeckSettings) -> list[str]:
    """The ``*CONTROLS`` cards of a step: iteration limits, and tolerances if asked."""
    out = [
        "** Stick/slip changes need more Newton iterations than the defaults allow before a",
        "** cut-back: divergence checks from iteration 8, at most 50 iterations, 10 cut-backs.",
        "*CONTROLS, PARAMETERS=TIME INCREMENTATION",
        "8, 10, 9, 50, 10, 4, 0, 10",
    ]
    if s.field_tolerance is None:
        return out
    tol = num(s.field_tolerance)
    out[-1] = "8, 10, 50, 50, 10, 4, 0, 10"
    return [
        *out[:2],
        "** The looser residual criterion is never used (its iteration I_P = 50, the limit).",
        *out[2:],
        "** Convergence: largest residual / average force, largest correction / largest",
        "** increment, and the residual criterion after I_P iterations.",
        "*CONTROLS, PARAMETERS=FIELD",
        f"{tol}, {tol}, , , {tol}",
    ]


def _segments(
    s: DeckSettings, k: int, previous: float, target: float
) -> list[tuple[float, float, float, float]]:
    """A stage as ccx steps: (step time, initial and largest increment, load factor at its end).

    One step, unless ``s.touch_increment_n`` refines the two bands of a reversal where the
    pin leaves one side of the free play and where it touches the other (five steps whose
    times add up to 1, so that the total time still counts stages); ``s.settle_increment_n``
    then sets the first increment of the step after the touch band.
    """
    n = max(2, s.increments_per_stage // 2) if k == 0 else s.increments_per_stage
    if s.touch_increment_n is None or k == 0 or target == previous:
        return [(1.0, 1.0 / n, 1.0 / n, target)]
    peak = s.peak_cload_n
    d = 1.0 if target > previous else -1.0
    spring = s.grip_spring * 2.0 * s.clearance_mm / peak  # load factor: the spring alone
    half = s.touch_band_n / peak
    # leave (-d·spring) and touch (+d·spring), each within a band of ±half, then the peak
    ends = [-d * spring - d * half, -d * spring + d * half]
    ends += [d * spring - d * half, d * spring + d * half, target]
    span = target - previous
    out, start = [], previous
    for j, end in enumerate(ends):
        period = (end - start) / span
        dt = s.touch_increment_n / (abs(span) * peak) if j in (1, 3) else 1.0 / n
        dt = min(dt, period)
        first = dt
        if j == 4 and s.settle_increment_n is not None:
            first = min(dt, s.settle_increment_n / (abs(span) * peak))
        out.append((period, first, dt, end))
        start = end
    return out


def steps(s: DeckSettings, roles: Roles, sign: float, dof: int) -> list[str]:
    """Return the ``*STEP`` blocks of every stage of ``s.load_factors``.

    Each ramps the grip's ``*CLOAD`` along deck DOF ``dof`` (``sign``: the LOAD face's
    outward normal) and prints the grip's U and the FIXED sets' total RF per increment.
    """
    out: list[str] = []
    previous = 0.0
    number = 0
    for k, target in enumerate(s.load_factors):
        start = previous
        segments = _segments(s, k, previous, target)
        for period, first, dt, end in segments:
            number += 1
            force = sign * end * s.peak_cload_n
            what = (
                f"grip force {start * s.amplitude_n:+g} -> {end * s.amplitude_n:+g} N"
                if len(segments) == 1
                else f"*CLOAD {sign * start * s.peak_cload_n:+.6g} -> {force:+.6g} N"
                f" (stage {k + 1}: to {target * s.amplitude_n:+g} N through the free play)"
            )
            out += [
                "**",
                f"** ==== Step {number}: {what}, ramped linearly over step time {period:.9g} ====",
                "** *STATIC: initial increment, step time, smallest increment, largest increment.",
                "*STEP, INC=10000",
                "*STATIC",
                f"{num(first)}, {num(period)}, {num(first * 1e-5)}, {num(dt)}",
                *_controls(s),
                "*CLOAD",
                f"{GRIP_REF_SET}, {dof}, {num(force)}",
                "** Per increment to the .dat file: the grip displacement, and the total reaction of",
                "** the fixed faces (minus the force carried through the hinge).",
                f"*NODE PRINT, NSET={GRIP_REF_SET}",
                "U",
            ]
            for name in roles.fixed:
                out += [f"*NODE PRINT, NSET={inp_name(name)}, TOTALS=ONLY", "RF"]
            out += [
                "** Fields for a viewer (.frd): displacements, stresses, contact status/stresses.",
                "*NODE FILE",
                "U",
                "*EL FILE",
                "S",
                "*CONTACT FILE",
                "CDIS, CSTR",
                "*END STEP",
            ]
            start = end
        previous = target
    return out
