"""Synthetic measurement sets: a model with hidden effects, measured as a test machine would.

``synthesize`` runs a model (``model.file.ModelSpec``) with extra, hidden
effects (``fe.effects``) at a design of (clearance, amplitude) cases and writes a
measurement set in the format of ``validation.measurements`` (``cases.csv`` + one loop
CSV per case) and a ``manifest.json`` holding the truth (effects and values, meshes, μ,
seed, the FE metrics of every case), which diagnosis tests read back.

No inverse crime: the data come from a finer, differently graded mesh and finer load
increments than the model that will be judged on them (``finer_mesh``,
``SYNTH_INCREMENT_FACTOR``).

Measurement model (``measure``): a force-controlled ramp between the turning points at
``force_rate_n_per_s`` with the crosshead limited to ``disp_rate_mm_per_s`` (so the free
play of a clearance is crossed at constant speed under almost no force), sampled at a
fixed clock ``sample_hz`` (the turning points fall between samples), after a dwell at
zero; then a load-cell and a displacement offset and Gaussian noise on both channels.
Every random number comes from ``numpy.random.default_rng([seed, case index])``, so a
set is reproducible from its seed and a case does not depend on the others.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError, check_range
from fe.cycle.result import CycleResult
from fe.kinds import DEFAULT_KIND, hinge_kind
from mesh.settings import MeshSettings
from model.jsonio import dumps
from model.spec import DesignPoint, ModelSpec

FloatArray = npt.NDArray[np.float64]

CONTACT_SIZE_FACTOR = 0.75
"""The synthetic data's contact (and slave) element size is the model's times this."""

GLOBAL_SIZE_FACTOR = 0.9
"""The synthetic data's global (and per-part) element size is the model's times this."""

ARC_GRADING_FACTOR = 1.5
"""The synthetic data's arc grading is the model's times this (capped at 100)."""

SYNTH_INCREMENT_FACTOR = 2
"""The synthetic data use this many times the model's increments per stage."""

MESH_RULE = (
    f"contact_size_mm × {CONTACT_SIZE_FACTOR}, size_mm and part sizes × {GLOBAL_SIZE_FACTOR}, "
    f"arc_grading × {ARC_GRADING_FACTOR} (≤ 100), increments_per_stage × {SYNTH_INCREMENT_FACTOR}"
)

SYNTH_AMPLITUDES_N = (100.0, 250.0, 400.0)
"""Amplitudes of the default design at each level [N]."""


def default_design(kind: str) -> tuple[tuple[float, tuple[float, ...]], ...]:
    """The default 9-case design of a kind: its design variable's ``synth_levels`` × 3 amplitudes.

    The general hinge: Δr 0, 0.1, 0.2 mm; the bearing hinge: F_p 0, 100, 200 N; a kind
    without a design variable: the amplitudes alone.
    """
    variables = hinge_kind(kind).design_variables
    levels = variables[0].synth_levels if variables else (0.0,)
    return tuple((x, SYNTH_AMPLITUDES_N) for x in levels)


@dataclass(frozen=True)
class SynthSettings:
    """How the synthetic test machine samples and disturbs a loop.

    Attributes:
        seed: Seed of every random number.
        noise_force_n: Standard deviation of the force noise [N].
        noise_disp_mm: Standard deviation of the displacement noise [mm].
        force_offset_n: Load-cell zero offsets are drawn uniformly in ± this [N].
        disp_offset_mm: Displacement zero offsets are drawn uniformly in ± this [mm].
        sample_hz: Sampling frequency [Hz].
        force_rate_n_per_s: Force rate of the ramps [N/s].
        disp_rate_mm_per_s: Crosshead speed limit [mm/s] (sets the time in the free play).
        dwell_s: Time recorded at zero before the loading starts [s].
    """

    seed: int = 0
    noise_force_n: float = 0.2
    noise_disp_mm: float = 5e-5
    force_offset_n: float = 1.0
    disp_offset_mm: float = 5e-3
    sample_hz: float = 20.0
    force_rate_n_per_s: float = 20.0
    disp_rate_mm_per_s: float = 0.01
    dwell_s: float = 2.0

    def __post_init__(self) -> None:
        if not isinstance(self.seed, int) or self.seed < 0:
            raise ParameterError(
                f"seed must be an integer ≥ 0, got {self.seed!r}", parameter="seed"
            )
        check_range("noise_force_n", self.noise_force_n, 0.0, 100.0)
        check_range("noise_disp_mm", self.noise_disp_mm, 0.0, 0.1)
        check_range("force_offset_n", self.force_offset_n, 0.0, 1000.0)
        check_range("disp_offset_mm", self.disp_offset_mm, 0.0, 10.0)
        check_range("sample_hz", self.sample_hz, 0.0, 1e5, lo_open=True)
        check_range("force_rate_n_per_s", self.force_rate_n_per_s, 0.0, 1e6, lo_open=True)
        check_range("disp_rate_mm_per_s", self.disp_rate_mm_per_s, 0.0, 100.0, lo_open=True)
        check_range("dwell_s", self.dwell_s, 0.0, 3600.0)


@dataclass(frozen=True)
class SynthCase:
    """One synthetic test.

    Attributes:
        case_id: Its name (``dr<Δr>mm_F<Fg>N``; ``fp<F_p>N_F<Fg>N`` for the bearing hinge:
            the design variable's ``case_tag`` and unit).
        amplitude_n: Force amplitude Fg [N].
        hinge: The hinge kind.
        values: Its design values as (name, value) pairs (e.g. ``(("clearance_mm", 0.1),)``).
    """

    case_id: str
    amplitude_n: float
    hinge: str = DEFAULT_KIND
    values: tuple[tuple[str, float], ...] = ()

    @property
    def design_value(self) -> float:
        """The case's design variable (Δr [mm], F_p [N]); 0 for a kind without one."""
        return self.values[0][1] if self.values else 0.0

    def record(self) -> dict[str, Any]:
        """The case as a flat JSON record: id, hinge, amplitude and each design value."""
        return {
            "case_id": self.case_id,
            "hinge": self.hinge,
            "amplitude_n": self.amplitude_n,
            **dict(self.values),
        }


def finer_mesh(mesh: MeshSettings, arc_factor: float = ARC_GRADING_FACTOR) -> MeshSettings:
    """Return the mesh the synthetic data are computed on (``MESH_RULE``).

    Args:
        mesh: The model's mesh settings.
        arc_factor: Factor on the arc grading (``ARC_GRADING_FACTOR``; ``synthesize``
            falls back to its inverse where the stronger grading distorts an element).
    """
    contact = mesh.contact_size_mm * CONTACT_SIZE_FACTOR
    return dataclasses.replace(
        mesh,
        size_mm=max(mesh.size_mm * GLOBAL_SIZE_FACTOR, contact),
        contact_size_mm=contact,
        part_sizes_mm=tuple((n, s * GLOBAL_SIZE_FACTOR) for n, s in mesh.part_sizes_mm),
        arc_grading=min(max(mesh.arc_grading * arc_factor, 1.0), 100.0),
    )


def design_cases(
    design: Sequence[tuple[float, Sequence[float]]], kind: str = DEFAULT_KIND, params: Any = None
) -> tuple[SynthCase, ...]:
    """Return the cases of a design (design value → amplitudes), in order.

    Args:
        design: Design value → amplitudes [N]; the value is the kind's design variable
            (the clearance [mm] of the general hinge, the preload [N] of the bearing hinge).
        kind: Hinge kind.
        params: The model's hinge parameters (their geometry bounds a design value,
            ``fe.kinds.DesignVariable.bounds``), or None.

    Raises:
        ParameterError: An unknown kind, a design value out of range, a non-positive
            amplitude, or a repeated case.
    """
    variables = hinge_kind(kind).design_variables[:1]
    out: list[SynthCase] = []
    seen: set[tuple[float, float]] = set()
    for x, amps in design:
        for v in variables:
            v.check(x, params)
        for amp in amps:
            check_range("amplitude_n", amp, 0.0, 1e6, lo_open=True)
            what = ", ".join([*(v.text(x) for v in variables), f"Fg = {amp:g} N"])
            if (x, amp) in seen:
                raise ParameterError(f"case {what} is repeated")
            seen.add((x, amp))
            tag = "".join(f"{v.case_tag}{x:g}{v.unit}_" for v in variables)
            values = tuple((v.name, float(x) + 0.0) for v in variables)
            out.append(SynthCase(f"{tag}F{amp:g}N", float(amp), hinge_kind(kind).name, values))
    if not out:
        raise ParameterError("the design has no cases")
    return tuple(out)


def parse_design(
    text: str, variable: str = "clearance_mm"
) -> tuple[tuple[float, tuple[float, ...]], ...]:
    """Parse ``"value:amp,amp,...;value:amp,..."``: clearance [mm] or preload [N], amplitudes [N].

    Raises:
        ParameterError: Naming the part that is not ``number:number[,number...]``.
    """
    design = []
    for part in filter(None, (p.strip() for p in text.split(";"))):
        head, sep, tail = part.partition(":")
        try:
            if not sep:
                raise ValueError
            amps = tuple(float(a) for a in tail.split(","))
            design.append((float(head), amps))
        except ValueError:
            raise ParameterError(
                f"--cases: {part!r} is not {variable}:amplitude_N[,amplitude_N...]"
            ) from None
    if not design:
        raise ParameterError(f"--cases: no cases in {text!r}")
    return tuple(design)


def machine_path(result: CycleResult) -> tuple[FloatArray, FloatArray]:
    """Return the loop the grips follow, free play crossed at zero force (``CycleResult.machine_path``)."""
    return result.machine_path()


@dataclass(frozen=True)
class Measured:
    """A synthetic record.

    Attributes:
        time_s: Sample times, shape (n,) [s].
        force_n: Force, shape (n,) [N] (offset and noise included).
        displacement_mm: Displacement, shape (n,) [mm] (offset and noise included).
        force_offset_n: The load-cell offset drawn [N].
        disp_offset_mm: The displacement offset drawn [mm].
    """

    time_s: FloatArray
    force_n: FloatArray
    displacement_mm: FloatArray
    force_offset_n: float
    disp_offset_mm: float


def measure(
    force_n: FloatArray, disp_mm: FloatArray, settings: SynthSettings, case_index: int
) -> Measured:
    """Sample a computed path as the test machine would (module docstring).

    Args:
        force_n: Force along the path, shape (n,) [N], starting at 0.
        disp_mm: Displacement along the path, shape (n,) [mm], starting at 0.
        settings: Sampling and noise.
        case_index: Index of the case (the second word of the random seed).

    Returns:
        The record; the inputs are not modified.
    """
    F = np.asarray(force_n, dtype=np.float64)
    d = np.asarray(disp_mm, dtype=np.float64)
    dt = np.maximum(
        np.abs(np.diff(F)) / settings.force_rate_n_per_s,
        np.abs(np.diff(d)) / settings.disp_rate_mm_per_s,
    )
    t_path = settings.dwell_s + np.concatenate([[0.0], np.cumsum(dt)])  # (n,) [s]
    t = np.arange(0.0, t_path[-1], 1.0 / settings.sample_hz)  # fixed clock
    F_s = np.interp(t, t_path, F, left=0.0)
    d_s = np.interp(t, t_path, d, left=0.0)
    rng = np.random.default_rng([settings.seed, case_index])
    f_off = float(rng.uniform(-1.0, 1.0)) * settings.force_offset_n
    d_off = float(rng.uniform(-1.0, 1.0)) * settings.disp_offset_mm
    F_s = F_s + f_off + rng.normal(0.0, settings.noise_force_n, t.size)
    d_s = d_s + d_off + rng.normal(0.0, settings.noise_disp_mm, t.size)
    return Measured(t, F_s, d_s, f_off, d_off)


def write_loop_csv(path: Path, m: Measured) -> Path:
    """Write a record as ``time_s,force_N,displacement_mm`` (9 significant digits)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(
        path,
        np.column_stack([m.time_s, m.force_n, m.displacement_mm]),
        delimiter=",",
        header="time_s,force_N,displacement_mm",
        comments="",
        fmt="%.9g",
    )
    return path


@dataclass(frozen=True)
class SynthReport:
    """What ``synthesize`` wrote.

    Attributes:
        out: The measurement folder.
        manifest: The manifest (also in ``out/manifest.json``).
    """

    out: Path
    manifest: dict[str, Any]


def synthesize(
    spec: ModelSpec,
    hidden: Mapping[str, Mapping[str, float]],
    cases: Sequence[SynthCase],
    settings: SynthSettings,
    out: Path,
    service: Any = None,
) -> SynthReport:
    """Compute and write a synthetic measurement set.

    Args:
        spec: The model (geometry, materials, μ, mesh, cycle, its own effects).
        hidden: Hidden effects, added to (and overriding) the model's own.
        cases: The tests.
        settings: Sampling and noise.
        out: Folder to write (``cases.csv``, ``loops/*.csv``, ``manifest.json``).
        service: The ``model.service.ModelService`` that runs the cycles (with a Dask
            runner: on its workers; the sampling and noise stay here); None: in process.

    Returns:
        The folder and the manifest.

    The set is written into a temporary folder beside ``out`` and renamed into place when
    every case is done, so a failure leaves no partial set; an existing ``out`` is replaced
    only if it is a synthetic set itself (it has a ``manifest.json``) or empty.

    Raises:
        ParameterError: A bad effect, a non-general hinge, an effect refused at a case, or
            an ``out`` that is a non-empty folder of something else.
        MeshQualityError: The data mesh has a distorted element with both arc gradings
            (the message names the clearance and what to change).
    """
    import shutil

    if out.exists() and any(out.iterdir()) and not (out / "manifest.json").is_file():
        raise ParameterError(
            f"--out {out} is a non-empty folder that is not a synthetic set: choose another"
        )
    tmp = out.parent / f".{out.name}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        report = _synthesize(spec, hidden, cases, settings, tmp, service)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    tmp.rename(out)
    return SynthReport(out, report.manifest)


def _data_runs(
    service: Any, data_spec: Any, cases: Sequence[SynthCase], adapted: dict[float, str]
) -> list[tuple[Any, dict[str, Any]]]:
    """Run every case on the data mesh; where its arc grading distorts an element, grade less.

    The cases go to the service as one batch (``ModelService.run_summarized``: on its Dask
    workers if it has a runner); those refused for a distorted element go again, once,
    with the softer grading.

    Returns:
        Per case, in order: (cycle result, the kind's summary of it).

    Raises:
        MeshQualityError: Both gradings distort an element (names the case).
        HingelabError: The first case's (in order) other error.
    """
    from cad.errors import MeshQualityError

    points = [DesignPoint(c.amplitude_n, dict(c.values)) for c in cases]
    done: list[Any] = service.run_summarized([(data_spec, p) for p in points])
    retry = [i for i, d in enumerate(done) if isinstance(d, MeshQualityError)]
    model_mesh = data_spec.mesh  # already finer: rebuild from its own rule
    softer = dataclasses.replace(
        model_mesh, arc_grading=max(1.0, model_mesh.arc_grading / ARC_GRADING_FACTOR**2)
    )
    alt = dataclasses.replace(data_spec, mesh=softer)
    again = service.run_summarized([(alt, points[i]) for i in retry])
    for i, d in zip(retry, again, strict=True):
        if isinstance(d, MeshQualityError):
            raise MeshQualityError(
                f"the synthetic-data mesh (contact size × {CONTACT_SIZE_FACTOR}, arc grading × "
                f"{ARC_GRADING_FACTOR} or ÷ {ARC_GRADING_FACTOR}) has a distorted element at "
                f"{cases[i].case_id} ({d}); give the model a finer mesh "
                "([mesh] size_mm / contact_size_mm) or less arc_grading"
            ) from done[i]
        adapted[cases[i].design_value] = (
            f"arc grading {model_mesh.arc_grading:g} distorted an element ({done[i]}); "
            f"used {softer.arc_grading:g}"
        )
        done[i] = d
    for d in done:
        if isinstance(d, BaseException):
            raise d
    return done


def _synthesize(
    spec: ModelSpec,
    hidden: Mapping[str, Mapping[str, float]],
    cases: Sequence[SynthCase],
    settings: SynthSettings,
    out: Path,
    service: Any,
) -> SynthReport:
    from fe.effects.registry import validate_effects
    from model.service import ModelService

    for c in cases:
        if c.hinge != spec.kind:
            raise ParameterError(
                f"case {c.case_id} is a {c.hinge}-hinge case, but the model is kind {spec.kind!r}"
            )
    truth = validate_effects({**spec.effects, **hidden})
    mesh_settings = finer_mesh(spec.mesh)
    n_inc = spec.cycle.increments_per_stage * SYNTH_INCREMENT_FACTOR
    data_spec = dataclasses.replace(
        spec,
        mesh=mesh_settings,
        cycle=dataclasses.replace(
            spec.cycle,
            increments_per_stage=n_inc,
            clearance_increments=SYNTH_INCREMENT_FACTOR * spec.cycle.clearance_increments,
            force_rate_n_per_s=settings.force_rate_n_per_s,  # the machine's clock
        ),
        effects=truth,
    )
    t0 = time.perf_counter()
    columns = [v.column for v in spec.hinge_kind.design_variables]
    rows = [",".join(["case_id", "hinge", *columns, "amplitude_N", "loop_file", "temperature_C"])]
    records: list[dict[str, Any]] = []
    index = {c.case_id: i for i, c in enumerate(cases)}
    service = ModelService() if service is None else service
    ordered = sorted(cases, key=lambda c: c.values)  # one geometry after the other
    adapted: dict[float, str] = {}
    runs = _data_runs(service, data_spec, ordered, adapted)
    for case, (result, summary) in zip(ordered, runs, strict=True):
        F, d = machine_path(result)
        m = measure(F, d, settings, index[case.case_id])
        loop_file = f"loops/{case.case_id}.csv"
        write_loop_csv(out / loop_file, m)
        metrics = result.metrics()
        records.append(
            {
                **case.record(),
                "loop_file": loop_file,
                "n_samples": int(m.time_s.size),
                "duration_s": float(m.time_s[-1]),
                "force_offset_N": m.force_offset_n,
                "disp_offset_mm": m.disp_offset_mm,
                "n_contact_points": int(summary.get("n_contact_points", 0)),
                "fe_metrics": {k: float(v) for k, v in metrics.items()},
            }
        )
    for c in cases:  # cases.csv in the order given
        design = [f"{x:g}" for _, x in c.values]
        row = [c.case_id, spec.kind, *design, f"{c.amplitude_n:g}", f"loops/{c.case_id}.csv", "21"]
        rows.append(",".join(row))
    out.mkdir(parents=True, exist_ok=True)
    (out / "cases.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    manifest = {
        "generator": "hingelab synth (validation.synth)",
        "hinge": spec.kind,
        "seed": settings.seed,
        "truth_effects": {k: dict(v) for k, v in truth.items()},
        "hidden_effects": {k: dict(v) for k, v in validate_effects(hidden).items()},
        "model_effects": {k: dict(v) for k, v in spec.effects.items()},
        "mu": spec.cycle.mu,
        "model_mesh": dataclasses.asdict(spec.mesh),
        "synth_mesh": dataclasses.asdict(mesh_settings),
        "mesh_rule": MESH_RULE,
        "mesh_adapted": {f"{c:g}": why for c, why in adapted.items()},
        "model_increments_per_stage": spec.cycle.increments_per_stage,
        "synth_increments_per_stage": n_inc,
        "measurement": dataclasses.asdict(settings),
        "cases": sorted(records, key=lambda r: index[r["case_id"]]),
        "wall_s": time.perf_counter() - t0,
    }
    (out / "manifest.json").write_text(dumps(manifest, indent=1) + "\n")
    return SynthReport(out, manifest)
