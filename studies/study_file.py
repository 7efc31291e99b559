"""A design study as a file: ``STUDY.toml`` → a validated ``Study`` (the model, its points, the surface).

Layout (every section optional except ``[design]``; an absent key keeps its default)::

    [study]     name = "..."           trace study name (default: the file's stem)
                description = "..."
                model = "MODEL.toml"   a model file to extend (relative to this file;
                                       default: the default general hinge); its kind,
                                       general or bearing, sets the design variables
    [hinge]     the number fields of the model's GeneralHingeParams (pin_radius_mm,
                lug_width_mm, ...; clearance_mm is a design variable) or BearingHingeParams
                (bore_mm, contact_angle_deg, ...; preload_n is a design variable)
    [mesh]      preset = "default" | "coarse" (general hinge: MeshSettings.coarse(), 4 mm /
                2 mm; bearing hinge without meshed balls: 4 mm / 0.8 mm, rings 1.2 mm; a
                cycle in seconds), then any number field of MeshSettings (size_mm, ...)
    [solver]    mu, increments (per half cycle, with and without clearance), and any
                number field of CycleSettings (increments_per_stage, clearance_increments,
                n_cycles, grading, tol, max_iter, contact_window, max_cutbacks)
    [design]    type = "full_factorial" | "latin_hypercube" | "central_composite"
                samples = N, seed = S        (latin_hypercube)
                face = "faced" | "inscribed" | "circumscribed", center = N   (central_composite)
    [design.clearance_mm]   general hinge: levels = [...] (full factorial) or min = .., max = ..
                            (the others)
    [design.preload_N]      bearing hinge: the same, in [0, 500] N (instead of clearance_mm)
    [design.amplitude_N]    the same; a variable left out stays at its fixed value
                            (clearance 0; the model's preload; the model's amplitude)
    [surface]   x = the varied variables (["clearance_mm", "amplitude_N"] or
                ["preload_N", "amplitude_N"]), y = "eta", degree = 1..4,
                threshold = η (optional: the region below it is shaded)

Everything is checked on load, before anything is meshed: an unknown section or key is
refused with the allowed ones listed, a wrong type names the key and the value, a value
out of range names the key, the value and the range, every design point is checked
against the model's ranges, and the surface must have at least as many points as terms.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cad.errors import DataError, ParameterError
from fe.kinds import DEFAULT_KIND, HingeKind, hinge_kind, kind_names

if TYPE_CHECKING:
    from model.spec import ModelSpec
    from studies.sweep import SweepSettings


def study_variables(kind: HingeKind) -> tuple[str, ...]:
    """What a study of a hinge kind may vary: its design variable and the amplitude.

    By the columns the sweep's trace and table give them (``studies.sweep_points.point_params``).
    """
    return (*(v.column for v in kind.design_variables[:1]), "amplitude_N")


RESPONSES = (
    "eta",
    "W_cycle_Nmm",
    "U_max_Nmm",
    "delta_max_mm",
    "disp_at_peak_mm",
    "secant_stiffness_N_per_mm",
    "friction_work_Nmm",
)
"""Results a surface may be fitted to (columns of ``table.csv``)."""

DESIGNS = ("full_factorial", "latin_hypercube", "central_composite")
FACES = ("faced", "inscribed", "circumscribed")
SECTIONS = ("study", "hinge", "mesh", "solver", "design", "surface")
MESH_PRESETS = ("default", "coarse")


@dataclass(frozen=True)
class SurfaceSpec:
    """The response surface a study fits at its end.

    Attributes:
        x: Input columns (design variables).
        y: Response column.
        degree: Total polynomial degree (1-4).
        threshold: Shade the region where y < threshold (None: none).
    """

    x: tuple[str, ...]
    y: str
    degree: int
    threshold: float | None = None


@dataclass(frozen=True)
class Study:
    """A validated study file.

    Attributes:
        path: The file.
        name: Study name in the trace.
        description: Free text.
        spec: The model (``model.spec.ModelSpec``).
        design: Design type.
        points: (design value, amplitude [N]) of every point, in design order; the design
            value is the clearance [mm] of the general hinge or the preload [N] of the
            bearing hinge (``variables``).
        surface: The surface to fit, or None.
    """

    path: Path
    name: str
    description: str
    spec: ModelSpec
    design: str
    points: tuple[tuple[float, float], ...]
    surface: SurfaceSpec | None

    @property
    def kind(self) -> str:
        """The name of the model's hinge kind."""
        return str(self.spec.kind)

    @property
    def variables(self) -> tuple[str, ...]:
        """The names of a point's values (trace parameters and table columns)."""
        return study_variables(self.spec.hinge_kind)

    def sweep_settings(self, *, workers: int = 1, scheduler: str | None = None) -> SweepSettings:
        """The ``studies.sweep.SweepSettings`` that run this study."""
        from studies.sweep import SweepSettings

        return SweepSettings(
            points=self.points,
            model=self.spec,
            mesh=self.spec.mesh,
            workers=workers,
            study=self.name,
            scheduler=scheduler,
        )


def _err(path: Path, section: str, msg: str) -> ParameterError:
    return ParameterError(f"{path}: [{section}] {msg}")


def _keys(
    table: dict[str, Any], allowed: tuple[str, ...] | list[str], path: Path, sec: str
) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise _err(path, sec, f"unknown key(s) {unknown}; allowed: {', '.join(allowed)}")


def _number(value: Any, key: str, path: Path, sec: str, *, integer: bool = False) -> Any:
    ok = isinstance(value, int) if integer else isinstance(value, int | float)
    if isinstance(value, bool) or not ok:
        what = "an integer" if integer else "a number"
        raise _err(path, sec, f"{key} must be {what}, got {value!r}")
    if not integer and not math.isfinite(value):
        raise _err(path, sec, f"{key} must be finite, got {value!r}")
    return value if integer else float(value)


def _table(doc: dict[str, Any], name: str, path: Path) -> dict[str, Any]:
    value = doc.get(name, {})
    if not isinstance(value, dict):
        raise _err(path, name, f"must be a table, got {value!r}")
    return value


def _override(
    obj: Any,
    table: dict[str, Any],
    path: Path,
    sec: str,
    skip: tuple[str, ...] = (),
    keys: dict[str, str] | None = None,
) -> Any:
    """Return ``obj`` with the table's number fields replaced, every key and range checked.

    ``keys``: field → the key the user wrote for it (``[solver] increments``), for messages.
    """
    fields = {
        f.name: getattr(obj, f.name)
        for f in dataclasses.fields(obj)
        if f.name not in skip and isinstance(getattr(obj, f.name), int | float | type(None))
    }
    _keys(table, list(fields), path, sec)
    values = {
        k: _number(
            v, k, path, sec, integer=isinstance(fields[k], int) and not isinstance(fields[k], bool)
        )
        for k, v in table.items()
    }
    try:
        return dataclasses.replace(obj, **values)
    except ParameterError as err:
        key = (keys or {}).get(err.parameter or "")
        raise _err(path, sec, str(err.renamed(key) if key else err)) from err


def _base_spec(study: dict[str, Any], path: Path) -> ModelSpec:
    from model.spec import ModelSpec

    model = study.get("model")
    if model is None:
        kind = hinge_kind(DEFAULT_KIND)
        return ModelSpec(kind.name, kind.params_type())
    if not isinstance(model, str):
        raise _err(path, "study", f"model must be a path (string), got {model!r}")
    from model.file import read_model

    return read_model(path.parent / model)


def _model(doc: dict[str, Any], study: dict[str, Any], path: Path) -> ModelSpec:
    from model.service import check_spec

    spec = _base_spec(study, path)
    check_spec(spec)
    kind = spec.hinge_kind
    design_fields = tuple(v.name for v in kind.design_variables)
    hinge = _override(spec.hinge, _table(doc, "hinge", path), path, "hinge", skip=design_fields)
    mesh_t = dict(_table(doc, "mesh", path))
    preset = mesh_t.pop("preset", None)
    mesh = spec.mesh
    if preset is not None:
        if preset not in MESH_PRESETS:
            raise _err(path, "mesh", f"preset must be one of {list(MESH_PRESETS)}, got {preset!r}")
        mesh = kind.mesh_settings(coarse=preset == "coarse")
    mesh = _override(mesh, mesh_t, path, "mesh")
    solver_t = dict(_table(doc, "solver", path))
    typed = {}
    if "increments" in solver_t:
        n = _number(solver_t.pop("increments"), "increments", path, "solver", integer=True)
        for k in ("increments_per_stage", "clearance_increments"):
            if k not in solver_t:
                solver_t[k], typed[k] = n, "increments"
    skip = ("amplitude_n", "blas_threads")
    cycle = _override(spec.cycle, solver_t, path, "solver", skip=skip, keys=typed)
    return dataclasses.replace(spec, hinge=hinge, mesh=mesh, cycle=cycle)


def _variable(design: dict[str, Any], name: str, design_type: str, path: Path) -> Any:
    """Levels (full factorial) or (min, max) (the others) of one variable, or None."""
    sec = f"design.{name}"
    table = design.get(name)
    if table is None:
        return None
    if not isinstance(table, dict):
        raise _err(path, sec, f"must be a table, got {table!r}")
    if design_type == "full_factorial":
        _keys(table, ("levels",), path, sec)
        levels = table.get("levels")
        if not isinstance(levels, list) or not levels:
            raise _err(path, sec, f"levels must be a non-empty list of numbers, got {levels!r}")
        values = [_number(v, "levels", path, sec) for v in levels]
        if len(set(values)) != len(values):
            raise _err(path, sec, f"levels must be distinct, got {values}")
        return values
    _keys(table, ("min", "max"), path, sec)
    if "min" not in table or "max" not in table:
        raise _err(path, sec, f"a {design_type} design needs min and max, got {table}")
    lo, hi = (_number(table[k], k, path, sec) for k in ("min", "max"))
    if not lo < hi:
        raise _err(path, sec, f"min must be < max, got min = {lo:g}, max = {hi:g}")
    return (lo, hi)


def _design(
    doc: dict[str, Any], spec: ModelSpec, path: Path
) -> tuple[str, list[tuple[float, float]]]:
    import numpy as np

    from rsm import design as doe

    design = _table(doc, "design", path)
    design_type = design.get("type", "full_factorial")
    if design_type not in DESIGNS:
        raise _err(path, "design", f"type must be one of {list(DESIGNS)}, got {design_type!r}")
    extra = {
        "full_factorial": (),
        "latin_hypercube": ("samples", "seed"),
        "central_composite": ("face", "center"),
    }
    names = study_variables(spec.hinge_kind)
    for other_kind in kind_names():
        other = study_variables(hinge_kind(other_kind))
        wrong = [v for v in other if v not in names and v in design]
        if wrong:
            raise _err(
                path,
                "design",
                f"{wrong[0]} is a design variable of the {other_kind} hinge; the model is the "
                f"{spec.kind} hinge, whose study varies {', '.join(names)}",
            )
    _keys(design, ["type", *names, *extra[design_type]], path, "design")
    found = {v: _variable(design, v, design_type, path) for v in names}
    varied = [v for v in names if found[v] is not None]
    if not varied:
        raise _err(path, "design", f"vary at least one of {list(names)} ([design.{names[0]}])")
    if design_type == "full_factorial":
        x = doe.full_factorial([found[v] for v in varied])
    elif design_type == "latin_hypercube":
        n = _number(design.get("samples", 10), "samples", path, "design", integer=True)
        seed = _number(design.get("seed", 0), "seed", path, "design", integer=True)
        if not 2 <= n <= 10_000:
            raise _err(path, "design", f"samples must be in [2, 10000], got {n}")
        x = doe.latin_hypercube([found[v] for v in varied], n, seed=seed)
    else:
        face = design.get("face", "faced")
        if face not in FACES:
            raise _err(path, "design", f"face must be one of {list(FACES)}, got {face!r}")
        center = _number(design.get("center", 1), "center", path, "design", integer=True)
        if len(varied) < 2 or not 0 <= center <= 20:
            raise _err(
                path,
                "design",
                f"central_composite needs both variables and center in [0, 20], got {varied}, {center}",
            )
        x = doe.central_composite(
            [found[v] for v in varied], face=doe.CompositeFace[face.upper()], n_center=center
        )
    fixed = {v.column: getattr(spec.hinge, v.name) for v in spec.hinge_kind.design_variables}
    fixed["amplitude_N"] = spec.cycle.amplitude_n
    cols = {v: (x[:, varied.index(v)] if v in varied else np.full(len(x), fixed[v])) for v in names}
    levels = cols[names[0]] if len(names) > 1 else np.zeros(len(x))
    points = [(float(c), float(a)) for c, a in zip(levels, cols["amplitude_N"], strict=True)]
    return design_type, points


def _check_points(points: list[tuple[float, float]], spec: ModelSpec, path: Path) -> None:
    from model.spec import DesignPoint, complete_point

    names = study_variables(spec.hinge_kind)
    variables = spec.hinge_kind.design_variables[:1]
    columns = {x.name: x.column for x in variables} | {"amplitude_n": "amplitude_N"}
    for i, (v, a) in enumerate(points):
        try:
            complete_point(spec, DesignPoint(a, {x.name: v for x in variables}))
        except ParameterError as err:  # named by the [design.<column>] the user wrote
            column = columns.get(err.parameter or "")
            where = f"{names[0]} = {v:g}, " if variables else ""
            raise _err(
                path,
                "design",
                f"point {i + 1} ({where}amplitude_N = {a:g}): {err.renamed(column) if column else err}",
            ) from err


def _surface(
    doc: dict[str, Any], n_points: int, varied: set[str], names: tuple[str, ...], path: Path
) -> SurfaceSpec | None:
    from math import comb

    table = doc.get("surface")
    if table is None:
        return None
    if not isinstance(table, dict):
        raise _err(path, "surface", f"must be a table, got {table!r}")
    _keys(table, ("x", "y", "degree", "threshold"), path, "surface")
    x = table.get("x", sorted(varied, key=names.index))
    if not isinstance(x, list) or not x or any(v not in varied for v in x):
        raise _err(
            path,
            "surface",
            f"x must list design variables the study varies {sorted(varied)}, got {x!r}",
        )
    y = table.get("y", "eta")
    if y not in RESPONSES:
        raise _err(path, "surface", f"y must be one of {list(RESPONSES)}, got {y!r}")
    degree = _number(table.get("degree", 2), "degree", path, "surface", integer=True)
    if not 1 <= degree <= 4:
        raise _err(path, "surface", f"degree must be in [1, 4], got {degree}")
    n_terms = comb(len(x) + degree, degree)
    if n_points < n_terms:
        raise _err(
            path,
            "surface",
            f"degree {degree} in {len(x)} variables has {n_terms} terms, but the design has only "
            f"{n_points} points; lower the degree or add points",
        )
    threshold = table.get("threshold")
    if threshold is not None:
        threshold = _number(threshold, "threshold", path, "surface")
    return SurfaceSpec(tuple(x), y, degree, threshold)


def read_study(path: Path | str) -> Study:
    """Read and validate a study file (see the module docstring for its layout).

    Raises:
        DataError: If the file is missing or not valid TOML.
        ParameterError: Naming the file, section, key, value and what is allowed.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: study file not found")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise DataError(f"{path}: not valid TOML: {err}") from err
    _keys(doc, SECTIONS, path, "top level")
    if "design" not in doc:
        raise _err(path, "design", "missing: a study needs a [design] section with its variables")
    study = _table(doc, "study", path)
    _keys(study, ("name", "description", "model"), path, "study")
    name = study.get("name", path.stem)
    description = study.get("description", "")
    if not isinstance(name, str) or not name.strip() or not isinstance(description, str):
        raise _err(
            path, "study", f"name and description must be text, got {name!r}, {description!r}"
        )
    spec = _model(doc, study, path)
    kind, points = _design(doc, spec, path)
    _check_points(points, spec, path)
    names = study_variables(spec.hinge_kind)
    unique = {(c + 0.0, a + 0.0) for c, a in points}
    index = {names[0]: 0, "amplitude_N": 1} if len(names) > 1 else {"amplitude_N": 1}
    varied = {v for v, i in index.items() if len({p[i] for p in unique}) > 1}
    surface = _surface(doc, len(unique), varied, names, path)
    return Study(path, name, description, spec, kind, tuple(points), surface)
