"""The effect framework: parameters, the context an effect sees, and the two hooks.

``Effect`` is the base of every candidate effect in ``fe.effects.models``; the registry and
the cycle with effects are in ``fe.effects`` (which explains the two hooks).
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

    def post(self, force_n: FloatArray, disp_mm: FloatArray, values: Values) -> FloatArray:
        """Return the displacement seen at the grips, shape (n,) [mm] (a new array).

        Args:
            force_n: Force, shape (n,) [N].
            disp_mm: Hinge displacement, shape (n,) [mm].
            values: Parameter → value.
        """
        return np.array(disp_mm, dtype=np.float64, copy=True)
