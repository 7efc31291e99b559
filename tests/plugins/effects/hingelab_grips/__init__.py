"""A compliance of the grips, registered as the effect ``grip_compliance`` (a test plug-in).

The grips' jaws add ``c F`` to the displacement under the force F: a linear spring in
series, found through the entry-point group ``hingelab.effects`` (nothing in hingelab
names it).
"""

from __future__ import annotations

from dataclasses import dataclass

from fe.effects.base import Effect, FloatArray, History, ParamSpec, Values


@dataclass(frozen=True)
class GripCompliance(Effect):
    """A linear spring ``c`` in series with the hinge; off at c = 0."""

    name: str = "grip_compliance"
    params: tuple[ParamSpec, ...] = (
        ParamSpec("grip_mm_per_n", 0.0, 1e-3, 1e-5, "mm/N", "compliance of the jaws"),
    )

    def post(self, history: History, values: Values) -> FloatArray:
        """Return ``δ + c F``, shape (n,) [mm]."""
        return history.disp_mm + values["grip_mm_per_n"] * history.force_n
