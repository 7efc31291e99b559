"""Parameter laws: an element parameter as a straight line in the test conditions.

A model file may say that a parameter of its hinge depends on a test condition of the
measured cases (a ``cond_<name>_<unit>`` column of cases.csv, ``Case.conditions``)::

    [laws.slip_force_n]          # F_s = 2000 N + 60 N per N of band tension
    intercept = 2000.0
    per_band_tension_N = 60.0

    [laws.damping_n_s_per_mm]    # a parameter with no per_… key is a fitted constant
    intercept = 8.0

At a case the parameter is ``intercept + Σ per_<condition> · condition`` (``ParamLaw``;
a key ``"per_<condition>^2"`` adds a term in the condition's square),
clipped into the parameter's range (``PARAM_RANGES``: a law that runs below zero at a
tension it was not fitted at means "none", not an error). A law replaces the hinge's own
value; a case's design value of the same parameter must then be 0 (the rig does not set
it). ``model.file.read_model`` leaves the ``[laws]`` section to this module:
``read_laws`` reads it, ``write_model_with_laws`` writes a model file with it. The laws
act where cases carry conditions (``compare``/``diagnose``/``calibrate`` on
displacement-controlled records, ``validation.stroke_fit``); ``hingelab cycle`` runs the
hinge's own values.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cad.errors import DataError, ParameterError
from model.file import write_model
from model.spec import ModelSpec
from validation.measurements import Case

SLOPE_PREFIX = "per_"

PARAM_RANGES = {
    "slip_asymmetry": (-0.95, 0.95),
    "slip_ratio": (0.0, 0.95),
    "k_tension_n_per_mm": (1e-3, 1e12),
    "k_compression_n_per_mm": (1e-3, 1e12),
}
"""Where a law's value is clipped; every other parameter to [0, ∞)."""


@dataclass(frozen=True)
class ParamLaw:
    """One parameter as a straight line in the test conditions.

    Attributes:
        param: The hinge parameter (a float field of the kind's parameters).
        intercept: Its value at zero conditions.
        slopes: Condition (``band_tension_N``) → change of the parameter per unit of it.
    """

    param: str
    intercept: float
    slopes: Mapping[str, float] = field(default_factory=dict)

    def value(self, conditions: Mapping[str, float], where: str = "") -> float:
        """The parameter at ``conditions``, clipped into ``PARAM_RANGES``.

        Raises:
            DataError: A condition the law needs that the case does not carry.
        """
        total = self.intercept
        for name, slope in self.slopes.items():
            base, power = condition_power(name)
            if base not in conditions:
                raise DataError(
                    f"{where or 'case'}: the law of {self.param} needs the condition "
                    f"cond_{base}, which the case does not have"
                )
            total += slope * conditions[base] ** power
        lo, hi = PARAM_RANGES.get(self.param, (0.0, math.inf))
        return min(max(total, lo), hi)

    def coefficients(self) -> dict[str, float]:
        """``{"<param>.intercept": …, "<param>.per_<condition>": …}`` (ledger and tables)."""
        out = {f"{self.param}.intercept": self.intercept}
        out.update({f"{self.param}.{SLOPE_PREFIX}{k}": v for k, v in self.slopes.items()})
        return out


Laws = Mapping[str, ParamLaw]


def condition_power(name: str) -> tuple[str, int]:
    """(condition, power) of a slope's name: ``band_tension_N`` → 1, ``band_tension_N^2`` → 2."""
    return (name[:-2], 2) if name.endswith(SQUARE) else (name, 1)


SQUARE = "^2"


def laws_from_table(table: Mapping[str, Any], params_type: Any, where: str) -> dict[str, ParamLaw]:
    """Laws from a ``[laws]`` table, checked against the kind's parameter fields.

    Raises:
        ParameterError: An unknown parameter or key, or a value that is not a number.
    """
    names = {f.name for f in dataclasses.fields(params_type)}
    out = {}
    for param, body in table.items():
        if param not in names:
            raise ParameterError(f"{where}: laws.{param}: not a parameter of the hinge")
        if not isinstance(body, Mapping):
            raise ParameterError(f"{where}: laws.{param} must be a table, got {body!r}")
        slopes, intercept = {}, 0.0
        for key, v in body.items():
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise ParameterError(f"{where}: laws.{param}.{key} must be a number, got {v!r}")
            if key == "intercept":
                intercept = float(v)
            elif key.startswith(SLOPE_PREFIX) and len(key) > len(SLOPE_PREFIX):
                slopes[key[len(SLOPE_PREFIX) :]] = float(v)
            else:
                raise ParameterError(
                    f"{where}: laws.{param}.{key}: allowed keys are intercept and "
                    f"{SLOPE_PREFIX}<condition> (e.g. per_band_tension_N)"
                )
        out[param] = ParamLaw(param, intercept, slopes)
    return out


def read_laws(path: Path | str, spec: ModelSpec) -> dict[str, ParamLaw]:
    """The ``[laws]`` of a model file (empty when it has none)."""
    path = Path(path)
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    return laws_from_table(doc.get("laws", {}), spec.hinge_kind.params_type, f"{path} [laws]")


def write_model_with_laws(spec: ModelSpec, laws: Laws, path: Path | str) -> Path:
    """Write the model file (``model.file.write_model``) and its ``[laws]`` sections."""
    path = write_model(spec, path)
    lines = []
    for law in laws.values():
        lines += ["", f"[laws.{law.param}]", f"intercept = {law.intercept!r}"]
        lines += [f'"{SLOPE_PREFIX}{k}" = {v!r}' for k, v in law.slopes.items()]
    text = path.read_text(encoding="utf-8") + "\n".join(lines) + ("\n" if lines else "")
    tmp = path.with_suffix(".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


def params_at(spec: ModelSpec, laws: Laws, case: Case) -> Any:
    """The hinge's parameters at a case: its design values, then the laws.

    Raises:
        DataError: A case that sets a parameter a law also gives, or that lacks a condition.
    """
    values = dict(case.values)
    for name in laws:
        if values.get(name, 0.0) != 0.0:
            raise DataError(
                f"case {case.case_id!r}: sets {name} = {values[name]:g}, which the model's "
                f"[laws.{name}] gives; set it to 0 in cases.csv or drop the law"
            )
        values.pop(name, None)
    where = f"case {case.case_id!r}"
    values.update({n: law.value(case.conditions, where) for n, law in laws.items()})
    try:
        return dataclasses.replace(spec.hinge, **values)
    except ParameterError as err:
        raise DataError(f"{where}: {err}") from err
