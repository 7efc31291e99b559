"""The effect framework: parameters, the context an effect sees, and the two hooks.

``Effect`` is the base of every candidate effect (the built-ins in ``fe.effects.models``,
a user's own in a file or an installed package, ``fe.effects.plugins``); the registry and
the cycle with effects are in ``fe.effects.registry`` (which explains the two hooks).
The ``post`` hook sees the loop's whole ``History`` (force, displacement and time), so a
rate- or time-dependent effect (a viscous element, creep) can be written; it returns the
new displacement, or a ``PostResult`` that also says how much of the work done on it is
stored (the rest is dissipated: ``fe.effects.registry.post_increments``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError
from fe.contact.state import ContactSettings
from fe.cycle.protocol import CycleSettings
from fe.general.system import HingeSystem
from fe.structure.condensed import Condensed

FloatArray = npt.NDArray[np.float64]
Values = Mapping[str, float]
"""Parameter name → value of one effect."""


def _frozen(values: npt.ArrayLike, name: str) -> FloatArray:
    a = np.array(values, dtype=np.float64, copy=True)
    if a.ndim != 1:
        raise ParameterError(f"History.{name} must have shape (n,), got {a.shape}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class History:
    """The loop an effect's ``post`` hook acts on: every sample from the unloaded start.

    The arrays are read-only copies (an effect cannot change its caller's data).

    Attributes:
        force_n: Force, shape (n,) [N]; ``force_n[0] = 0`` (the unloaded start).
        disp_mm: Hinge displacement (with the effects applied before this one), shape (n,) [mm].
        time_s: Time of each sample from the start, non-decreasing, shape (n,) [s]: the
            protocol's (``CycleSettings.force_rate_n_per_s``) or a measured record's
            (``fe.effects.history.time_from_reference``).
    """

    force_n: FloatArray
    disp_mm: FloatArray
    time_s: FloatArray

    def __post_init__(self) -> None:
        for name in ("force_n", "disp_mm", "time_s"):
            object.__setattr__(self, name, _frozen(getattr(self, name), name))
        n = self.force_n.shape
        if self.disp_mm.shape != n or self.time_s.shape != n:
            raise ParameterError(
                f"History: force_n {n}, disp_mm {self.disp_mm.shape} and time_s "
                f"{self.time_s.shape} must have one shape"
            )
        if n[0] > 1 and np.any(np.diff(self.time_s) < 0.0):
            raise ParameterError("History.time_s must not decrease")

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.force_n.shape[0])


@dataclass(frozen=True)
class PostResult:
    """What a ``post`` hook may return instead of the bare displacement.

    Attributes:
        disp_mm: Displacement seen at the grips, shape (n,) [mm].
        stored_energy_nmm: Energy stored in the effect's element at each sample, shape
            (n,) [N·mm]; the rest of the work ``∫F dh`` done on it (h its displacement) is
            dissipated. None: all of it is stored (a rate-independent element ``h(F)``,
            whose work over a closed loop is zero).
    """

    disp_mm: FloatArray
    stored_energy_nmm: FloatArray | None = None


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an effect.

    Attributes:
        name: Parameter name (with its unit, e.g. ``compliance_mm_per_n``).
        lo: Lowest allowed value (the effect is off at ``lo`` = 0).
        hi: Highest allowed value.
        default: Value used when the parameter is not given (a typical strength).
        unit: Unit, for reports.
        doc: One line: what it is.
    """

    name: str
    lo: float
    hi: float
    default: float
    unit: str
    doc: str

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and self.lo <= self.hi):
            raise ParameterError(
                f"{self.name}: range must be finite with lo ≤ hi, got [{self.lo}, {self.hi}]"
            )
        if not self.lo <= self.default <= self.hi:
            raise ParameterError(
                f"{self.name}: default must be in [{self.lo:g}, {self.hi:g}], got {self.default:g}"
            )


def map_configs(
    configs: Mapping[int, Condensed], change: Callable[[Condensed], Condensed]
) -> dict[int, Condensed]:
    """Apply ``change`` to every configuration once, keeping shared ones shared (Δr = 0: +1 is −1)."""
    done: dict[int, Condensed] = {}
    out: dict[int, Condensed] = {}
    for side, cond in configs.items():
        if id(cond) not in done:
            done[id(cond)] = change(cond)
        out[side] = done[id(cond)]
    return out


def add_diagonal(cond: Condensed, components: tuple[int, ...], c_mm3_per_n: float) -> Condensed:
    """Return ``cond`` with ``W[3i+k, 3i+k] += c / A_i`` for k in ``components`` [mm/N]."""
    W = np.array(cond.W, dtype=np.float64, copy=True)
    m = len(cond.geo.slave)
    add = c_mm3_per_n / cond.geo.area_mm2  # (m,) [mm/N]
    for k in components:
        idx = 3 * np.arange(m, dtype=np.int64) + k
        W[idx, idx] += add
    return dataclasses.replace(cond, W=W)


@dataclass(frozen=True)
class EffectContext:
    """What an effect's ``apply`` may use besides the configurations.

    Attributes:
        system: The factorised hinge the configurations were condensed from.
        settings: The cycle's protocol and contact settings (μ, tolerance).
    """

    system: HingeSystem
    settings: CycleSettings

    def contact(self) -> ContactSettings:
        """Return the contact-solver settings of the cycle."""
        return self.contact_of(self.settings)

    @staticmethod
    def contact_of(settings: CycleSettings) -> ContactSettings:
        """Return the contact-solver settings of a cycle's settings."""
        return settings.contact()


@dataclass(frozen=True)
class Effect:
    """A physical effect: its parameters and two hooks, identities here.

    Attributes:
        name: Registry name.
        params: Its parameters.
        zero_clearance_reason: Why the effect needs Δr = 0 ("" if it does not).
        kinds: Hinge kinds (``model.spec.HingeKind`` values) whose solve the effect changes;
            an effect that acts only on the loop (``apply`` left as the identity) applies
            to every kind (``applies_to``).
    """

    name: str
    params: tuple[ParamSpec, ...]
    zero_clearance_reason: str = ""
    kinds: tuple[str, ...] = ("general",)

    def applies_to(self, kind: str) -> bool:
        """True if the effect can act on a hinge of ``kind`` (``general`` or ``bearing``)."""
        return kind in self.kinds or type(self).apply is Effect.apply

    def apply(
        self, configs: Mapping[int, Condensed], values: Values, ctx: EffectContext
    ) -> dict[int, Condensed]:
        """Return the configurations with the effect (new objects; the input is not modified).

        Args:
            configs: Side (+1 tension, −1 compression) → condensed configuration.
            values: Parameter → value (validated, every parameter present).
            ctx: The factorised hinge and the cycle settings.
        """
        return dict(configs)

    def refuse_clearance(self, configs: Mapping[int, Condensed], param: str, value: float) -> None:
        """Raise if the configurations have clearance (two touching configurations).

        Raises:
            ParameterError: Naming ``effects.<name>.<param>``, its value and the reason.
        """
        if configs.get(1) is not configs.get(-1):
            spec = next(p for p in self.params if p.name == param)
            raise ParameterError(
                f"effects.{self.name}.{param} = {value:g} {spec.unit} needs a hinge without "
                f"clearance ({self.zero_clearance_reason}): clearance_mm must be 0"
            )

    def post(self, history: History, values: Values) -> FloatArray | PostResult:
        """Return the displacement seen at the grips, shape (n,) [mm] (a new array).

        It must map the unloaded start (F = 0 at t = 0) to δ = 0. Return a ``PostResult``
        to say how much energy the element stores (a viscous one dissipates).

        Args:
            history: Force, displacement and time of every sample (read-only).
            values: Parameter → value.
        """
        return np.array(history.disp_mm, dtype=np.float64, copy=True)
