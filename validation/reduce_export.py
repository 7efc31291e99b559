"""What ``hingelab reduce`` writes besides the model file: NASTRAN cards and an FMU.

* :func:`equivalent_linear` / :func:`pbush_cards` — the equivalent-linear hinge of a
  spacecraft structural model: at each amplitude Fg the user names, the secant stiffness
  K = 2Fg/(δ(+Fg) − δ(−Fg)) of the element's steady loop (free play included: a linear
  model cannot have a dead zone, so its secant spans it) and the structural damping
  GE = η (for light damping GE = 2ζ ≈ η at resonance). Equivalent linearisation holds
  where the hinge's response in the structure stays near that amplitude (a mode whose
  hinge force amplitude is about the Fg the card was made at), for light damping
  (η ≲ 0.1) and without impacts: across the free play at low amplitude, in transients
  that sweep the amplitude, or where sub/super-harmonics matter (rattling in the play),
  run the nonlinear element instead.
* :func:`write_fmu` — an FMI 2.0 co-simulation FMU through ``pythonfmu``: the element
  driven by the displacement u (input) returns the force F (output), the element's
  parameters being FMU parameters. The FMU runs the same ``fe.joint`` code in the
  Python that built it (``pythonfmu``'s runtime embeds that interpreter), so it needs
  that environment with hingelab installed where it is simulated.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fe.joint.element import JointParams
from fe.joint.history import force_history


@dataclasses.dataclass(frozen=True)
class LinearHinge:
    """The equivalent-linear hinge at one amplitude: Fg [N], K [N/mm], GE, δ(±Fg) [mm]."""

    amplitude_n: float
    stiffness_n_per_mm: float
    ge: float
    d_plus_mm: float
    d_minus_mm: float


def equivalent_linear(params: JointParams, amplitude_n: float, cycles: int = 2) -> LinearHinge:
    """The secant stiffness and GE = η of the element's steady loop ±Fg (force control)."""
    f = amplitude_n * np.concatenate(
        [np.linspace(0, 1, 51)[1:]]
        + [np.linspace(1, -1, 101)[1:], np.linspace(-1, 1, 101)[1:]] * cycles
    )
    h = force_history(params, f)
    loop = slice(f.size - 200 - 1, f.size)
    u = h.disp_mm[loop]
    w = float(h.dissipation_nmm[-1] - h.dissipation_nmm[loop.start])
    dp, dm = float(u[-1]), float(u[np.argmin(f[loop])])
    k = 2 * amplitude_n / (dp - dm)
    return LinearHinge(
        amplitude_n, k, w / (2 * math.pi * 0.5 * amplitude_n * 0.5 * (dp - dm)), dp, dm
    )


def _field(value: float | int | str) -> str:
    """One 8-character NASTRAN small field."""
    if not isinstance(value, float):
        return f"{value!s:<8s}"[:8]
    for digits in range(5, -1, -1):  # NASTRAN's short exponent: 1.2346+5, as many digits as fit
        mantissa, exponent = f"{value:.{digits}E}".split("E")
        text = f"{mantissa}{int(exponent):+d}"
        if len(text) <= 8:
            return f"{text:<8s}"
    raise ValueError(f"{value!r} does not fit a NASTRAN small field")


def pbush_cards(params: JointParams, amplitudes_n: Sequence[float], pid0: int = 1) -> str:
    """A CBUSH/PBUSH card set per amplitude (direction 1 = the hinge's load line)."""
    lines = [
        "$ hingelab reduce: equivalent-linear hinge (secant K, GE = eta) per amplitude",
        "$ direction 1 is the hinge's load line; K2..K6 are not modelled by the element",
        "$ (fill them from the hinge's other stiffnesses). Valid near the named amplitude,",
        "$ for light damping, without impacts across the free play (docs/joint_element.md).",
    ]
    for i, amp in enumerate(amplitudes_n):
        lin = equivalent_linear(params, float(amp))
        pid = pid0 + i
        lines += [
            f"$ Fg = {amp:g} N: K = {lin.stiffness_n_per_mm:.6g} N/mm, GE = {lin.ge:.6g}",
            "".join(_field(v) for v in ("CBUSH", pid, pid, 1, 2, "", "", "", 0)).rstrip(),
            "".join(_field(v) for v in ("PBUSH", pid, "K", lin.stiffness_n_per_mm)).rstrip(),
            "".join(_field(v) for v in ("", "GE", lin.ge)).rstrip(),
        ]
    return "\n".join(lines) + "\n"


FMU_SLAVE = '''"""The hingelab reduced-order joint as an FMI 2.0 co-simulation slave (pythonfmu)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

from fe.joint.element import JointParams, initial_state
from fe.joint.step import step

PARAMS = {params!r}


class HingelabJoint(Fmi2Slave):
    author = "hingelab reduce"
    description = "Reduced-order hinge joint: displacement u [mm] in, force F [N] out"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.F = 0.0
        self.K = 0.0
        for name, value in PARAMS.items():
            setattr(self, name, float(value))
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("F", causality=Fmi2Causality.output))
        self.register_variable(Real("K", causality=Fmi2Causality.output))
        self._state = None

    def _params(self):
        values = {{n: getattr(self, n) for n in PARAMS}}
        values["n_branches"] = int(round(values["n_branches"]))
        return JointParams(**values)

    def do_step(self, current_time, step_size):
        p = self._params()
        if self._state is None:
            self._state = initial_state(p)
        out = step(p, self._state, self.u, step_size if p.damping_n_s_per_mm else None)
        self._state = out.state
        self.F = out.force_n
        self.K = out.tangent_n_per_mm
        return True
'''


def write_fmu(params: JointParams, dest: Path) -> Path:
    """Build the FMU (``pythonfmu build``) into ``dest`` (a ``.fmu`` file); return it.

    Raises:
        ImportError: If pythonfmu is not installed.
    """
    from pythonfmu.builder import FmuBuilder

    values = {k: float(v) for k, v in dataclasses.asdict(params).items()}
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "hingelab_joint.py"
        script.write_text(FMU_SLAVE.format(params=values))
        built = FmuBuilder.build_FMU(script, dest=tmp)
        dest.parent.mkdir(parents=True, exist_ok=True)
        part = dest.with_suffix(".fmu.part")
        shutil.copyfile(built, part)
        part.replace(dest)
    return dest
