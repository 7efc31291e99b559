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
from typing import Any

from cad.errors import DataError, ParameterError

VARIABLES: dict[str, tuple[str, str]] = {
    "general": ("clearance_mm", "amplitude_N"),
    "bearing": ("preload_N", "amplitude_N"),
}
"""What a study of each hinge kind may vary: (design value, amplitude), the fields of
``model.spec.DesignPoint`` under the names the sweep's trace and table give them
(``studies.sweep_points.point_params``)."""

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
    spec: Any
    design: str
    points: tuple[tuple[float, float], ...]
    surface: SurfaceSpec | None

    @property
    def kind(self) -> str:
        """The hinge kind of the model, ``general`` or ``bearing``."""
        return str(self.spec.kind)

    @property
    def variables(self) -> tuple[str, str]:
        """The names of a point's two values (trace parameters and table columns)."""
        return VARIABLES[self.kind]

    def sweep_settings(self, *, workers: int = 1, scheduler: str | None = None) -> Any:
        """The ``studies.sweep.SweepSettings`` that run this study."""
        from studies.sweep import SweepSettings

        return SweepSettings(
            points_mm_n=self.points,
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
    obj: Any, table: dict[str, Any], path: Path, sec: str, skip: tuple[str, ...] = ()
) -> Any:
    """Return ``obj`` with the table's number fields replaced, every key and range checked."""
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
        raise _err(path, sec, str(err)) from err


def _base_spec(study: dict[str, Any], path: Path) -> Any:
    from cad.general import GeneralHingeParams
    from model.spec import ModelSpec

    model = study.get("model")
    if model is None:
        return ModelSpec("general", GeneralHingeParams())
    if not isinstance(model, str):
        raise _err(path, "study", f"model must be a path (string), got {model!r}")
    from model.file import read_model

    return read_model(path.parent / model)


def _model(doc: dict[str, Any], study: dict[str, Any], path: Path) -> Any:
    from mesh.settings import MeshSettings
    from model.service import check_spec

    spec = _base_spec(study, path)
    check_spec(spec)
    if spec.kind not in VARIABLES:
        raise _err(
            path,
            "study",
            f"model: a study needs a {' or '.join(VARIABLES)} model, got {spec.kind!r}",
        )
    bearing = spec.kind == "bearing"
    design_field = "preload_n" if bearing else "clearance_mm"
    hinge = _override(spec.hinge, _table(doc, "hinge", path), path, "hinge", skip=(design_field,))
    mesh_t = dict(_table(doc, "mesh", path))
    preset = mesh_t.pop("preset", None)
    mesh = spec.mesh
    if preset is not None:
        if preset not in MESH_PRESETS:
            raise _err(path, "mesh", f"preset must be one of {list(MESH_PRESETS)}, got {preset!r}")
        if bearing:
            # both ball models run on the structure meshed without balls (``full`` brings
            # its own meshed ball, fe.bearing.ball_rig)
            mesh = MeshSettings.for_hinge("bearing", balls=False)
            if preset == "coarse":
                mesh = dataclasses.replace(
                    mesh, size_mm=4.0, contact_size_mm=0.8, part_sizes_mm=(("ring", 1.2),)
                )
        else:
            mesh = MeshSettings.coarse() if preset == "coarse" else MeshSettings()
    mesh = _override(mesh, mesh_t, path, "mesh")
    solver_t = dict(_table(doc, "solver", path))
    if "increments" in solver_t:
        n = _number(solver_t.pop("increments"), "increments", path, "solver", integer=True)
        for k in ("increments_per_stage", "clearance_increments"):
            solver_t.setdefault(k, n)
    cycle = _override(spec.cycle, solver_t, path, "solver", skip=("amplitude_n", "blas_threads"))
    return dataclasses.replace(spec, hinge=hinge, mesh=mesh, cycle=cycle)


def _variable(design: dict[str, Any], name: str, kind: str, path: Path) -> Any:
    """Levels (full factorial) or (min, max) (the others) of one variable, or None."""
    sec = f"design.{name}"
    table = design.get(name)
    if table is None:
        return None
    if not isinstance(table, dict):
        raise _err(path, sec, f"must be a table, got {table!r}")
    if kind == "full_factorial":
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
        raise _err(path, sec, f"a {kind} design needs min and max, got {table}")
    lo, hi = (_number(table[k], k, path, sec) for k in ("min", "max"))
    if not lo < hi:
        raise _err(path, sec, f"min must be < max, got min = {lo:g}, max = {hi:g}")
    return (lo, hi)


def _design(doc: dict[str, Any], spec: Any, path: Path) -> tuple[str, list[tuple[float, float]]]:
    import numpy as np

    from rsm import design as doe

    design = _table(doc, "design", path)
    kind = design.get("type", "full_factorial")
    if kind not in DESIGNS:
        raise _err(path, "design", f"type must be one of {list(DESIGNS)}, got {kind!r}")
    extra = {
        "full_factorial": (),
        "latin_hypercube": ("samples", "seed"),
        "central_composite": ("face", "center"),
    }
    names = VARIABLES[spec.kind]
    for other_kind, other in VARIABLES.items():
        wrong = [v for v in other if v not in names and v in design]
        if wrong:
            raise _err(
                path,
                "design",
                f"{wrong[0]} is a design variable of the {other_kind} hinge; the model is the "
                f"{spec.kind} hinge, whose study varies {', '.join(names)}",
            )
    _keys(design, ["type", *names, *extra[kind]], path, "design")
    found = {v: _variable(design, v, kind, path) for v in names}
    varied = [v for v in names if found[v] is not None]
    if not varied:
        raise _err(path, "design", f"vary at least one of {list(names)} ([design.{names[0]}])")
    if kind == "full_factorial":
        x = doe.full_factorial([found[v] for v in varied])
    elif kind == "latin_hypercube":
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
    value = spec.hinge.preload_n if spec.kind == "bearing" else 0.0
    fixed = dict(zip(names, (value, spec.cycle.amplitude_n), strict=True))
    cols = {v: (x[:, varied.index(v)] if v in varied else np.full(len(x), fixed[v])) for v in names}
    points = [(float(c), float(a)) for c, a in zip(cols[names[0]], cols[names[1]], strict=True)]
    return kind, points


def _check_points(points: list[tuple[float, float]], kind: str, path: Path) -> None:
    from model.spec import DesignPoint

    name, amp = VARIABLES[kind]
    for i, (v, a) in enumerate(points):
        try:
            if kind == "bearing":
                DesignPoint(amplitude_n=a, preload_n=v)
            else:
                DesignPoint(amplitude_n=a, clearance_mm=v)
        except ParameterError as err:
            raise _err(
                path, "design", f"point {i + 1} ({name} = {v:g}, {amp} = {a:g}): {err}"
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
    _check_points(points, spec.kind, path)
    names = VARIABLES[spec.kind]
    unique = {(c + 0.0, a + 0.0) for c, a in points}
    varied = {v for v, i in zip(names, (0, 1), strict=True) if len({p[i] for p in unique}) > 1}
    surface = _surface(doc, len(unique), varied, names, path)
    return Study(path, name, description, spec, kind, tuple(points), surface)
