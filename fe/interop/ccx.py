"""Run CalculiX (``ccx``) on a deck and read the load–displacement history from its ``.dat``.

The decks of :mod:`fe.interop.inp` print, in every increment, the grip reference node's
displacement (``*NODE PRINT, NSET=grip_ref`` → ``U``) and the total reaction of each fixed
face (``*NODE PRINT, ..., TOTALS=ONLY`` → ``RF``). CalculiX writes each as a block::

     displacements (vx,vy,vz) for set GRIP_REF and time  0.1000000E+01

           924  3.918476E-03  0.000000E+00  0.000000E+00

     total force (fx,fy,fz) for set TANG_FIXED and time  0.1000000E+01

           -4.000000E+02  1.2E-12  3.4E-13

``time`` is the total time: step k (1-based) runs from k − 1 to k. ``parse_dat`` returns
every block; ``loop_from_dat`` pairs them into the loop (grip displacement, force through
the hinge = minus the summed reactions of the fixed faces).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError, DataError, SolverError

FloatArray = npt.NDArray[np.float64]

_HEADER = re.compile(
    r"^\s*(?P<what>[a-z][a-z ]*?)\s*\((?P<cols>[^)]*)\)\s+for set\s+(?P<set>\S+)\s+"
    r"and time\s+(?P<time>\S+)\s*$"
)


@dataclass(frozen=True)
class DatBlock:
    """One output block of a ``.dat`` file.

    Attributes:
        what: The quantity as ccx names it, e.g. ``"displacements"``, ``"total force"``.
        set_name: The node or element set (upper case, as ccx writes it).
        time: Total time of the increment.
        rows: The numbers, shape (n_rows, n_cols) float64; for per-node output the first
            column is the node number.
    """

    what: str
    set_name: str
    time: float
    rows: FloatArray


_FORTRAN_EXP = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([+-]\d{3})$")
"""A Fortran ``E13.6`` number whose exponent needs three digits: ccx writes ``-5.260560-144``
(the ``E`` dropped to make room), which ``float`` does not read."""


def _number(text: str) -> float:
    """A number of a ``.dat`` row, including Fortran's three-digit exponents without ``E``."""
    try:
        return float(text)
    except ValueError:
        m = _FORTRAN_EXP.match(text)
        if m is None:
            raise
        return float(f"{m[1]}e{m[2]}")


def parse_dat(path: Path) -> list[DatBlock]:
    """Read every output block of a CalculiX ``.dat`` file, in file order.

    Raises:
        DataError: If the file is missing or a block holds a line that is not numbers.
    """
    if not path.is_file():
        raise DataError(f"{path}: no such .dat file")
    blocks: list[DatBlock] = []
    head: re.Match[str] | None = None
    rows: list[list[float]] = []

    def close() -> None:
        if head is not None:
            width = max((len(r) for r in rows), default=0)
            arr = np.array([r + [np.nan] * (width - len(r)) for r in rows], dtype=np.float64)
            blocks.append(
                DatBlock(
                    head["what"], head["set"], float(head["time"]), arr.reshape(len(rows), width)
                )
            )

    for lineno, line in enumerate(path.read_text(errors="replace").splitlines(), start=1):
        m = _HEADER.match(line)
        if m:
            close()
            head, rows = m, []
        elif line.strip() and head is not None:
            try:
                rows.append([_number(x) for x in line.split()])
            except ValueError as err:
                raise DataError(f"{path}:{lineno}: expected numbers, got {line.strip()!r}") from err
    close()
    return blocks


@dataclass(frozen=True)
class StaSummary:
    """What a ccx ``.sta`` file says about the Newton iterations of a run.

    Attributes:
        increments: Converged increments.
        iterations: Newton iterations, those of failed attempts included.
        cutbacks: Failed attempts (an increment reattempted at a smaller size).
        last_time: Total time of the last converged increment (step k ends at k).
    """

    increments: int
    iterations: int
    cutbacks: int
    last_time: float


def parse_sta(path: Path) -> StaSummary:
    """Summarise a CalculiX ``.sta`` file (one line per attempt; a failed one ends in U).

    Raises:
        DataError: If the file is missing or an attempt line is malformed.
    """
    if not path.is_file():
        raise DataError(f"{path}: no such .sta file")
    increments = iterations = cutbacks = 0
    last = 0.0
    for lineno, line in enumerate(path.read_text(errors="replace").splitlines(), start=1):
        cols = line.split()
        if len(cols) != 7 or not cols[0].isdigit():  # the two header lines
            continue
        try:
            iterations += int(cols[3])
            failed = cols[2].endswith("U")
            if not failed:
                last = float(cols[4])
        except ValueError as err:
            raise DataError(f"{path}:{lineno}: not an attempt line: {line.strip()!r}") from err
        cutbacks += failed
        increments += not failed
    return StaSummary(increments, iterations, cutbacks, last)


@dataclass(frozen=True)
class CcxLoop:
    """The load–displacement history of a deck's run, one entry per converged increment.

    Attributes:
        time: Total time, shape (n,); step k spans (k − 1, k].
        step: Step number (1-based), shape (n,) int64.
        grip_disp_mm: Grip reference node displacement along the load DOF [mm], shape (n,).
        hinge_force_n: Force through the hinge: minus the summed reactions of the fixed
            faces along the load DOF [N], shape (n,).
    """

    time: FloatArray
    step: npt.NDArray[np.int64]
    grip_disp_mm: FloatArray
    hinge_force_n: FloatArray


def loop_from_dat(
    blocks: Sequence[DatBlock], grip_set: str, fixed_sets: Sequence[str], dof: int = 1
) -> CcxLoop:
    """Pair the grip displacement and the fixed faces' reactions of every increment.

    Args:
        blocks: From ``parse_dat``.
        grip_set: The grip reference node set (``fe.interop.inp_names.GRIP_REF_SET``).
        fixed_sets: The fixed faces' node sets (their totals are summed).
        dof: Load direction, 1-3.

    Returns:
        The history, with a leading (0, 0) point at time 0.

    Raises:
        DataError: If an increment lacks one of the sets.
    """
    grip = grip_set.upper()
    fixed = {s.upper() for s in fixed_sets}
    disp: dict[float, float] = {}
    force: dict[float, float] = {}
    for b in blocks:
        if b.set_name == grip and b.what == "displacements":
            disp[b.time] = float(b.rows[0, dof])
        elif b.set_name in fixed and b.what == "total force":
            force[b.time] = force.get(b.time, 0.0) - float(b.rows[0, dof - 1])
    if set(disp) != set(force):
        raise DataError(
            f"increments without both {grip} displacement and {sorted(fixed)} reactions: "
            f"{sorted(set(disp) ^ set(force))[:5]}"
        )
    t = np.array([0.0, *sorted(disp)], dtype=np.float64)
    return CcxLoop(
        time=t,
        step=np.maximum(np.ceil(t - 1e-9), 1).astype(np.int64),
        grip_disp_mm=np.array([0.0, *(disp[x] for x in t[1:])], dtype=np.float64),
        hinge_force_n=np.array([0.0, *(force[x] for x in t[1:])], dtype=np.float64),
    )


@dataclass(frozen=True)
class CcxRun:
    """A finished ccx run.

    Attributes:
        dat: The ``.dat`` file.
        frd: The ``.frd`` file (fields for cgx or ParaView converters).
        log: ccx's standard output and error.
        wall_s: Wall time [s].
        peak_rss_mb: Peak resident memory of ccx [MB] (0 where the OS does not say).
    """

    dat: Path
    frd: Path
    log: Path
    wall_s: float
    peak_rss_mb: float


def find_ccx(executable: str = "ccx") -> str | None:
    """Return the path of the ccx executable, or None if it is not installed."""
    return shutil.which(executable)


def run_ccx(
    deck: Path, *, executable: str = "ccx", threads: int = 1, timeout_s: float = 3600.0
) -> CcxRun:
    """Run ccx on ``deck`` in its folder (results next to it: ``.dat``, ``.frd``, ``.sta``).

    Args:
        deck: The ``.inp`` file.
        executable: ccx's name or path.
        threads: OpenMP threads ccx may use (solver and element loops).
        timeout_s: Give up after this long [s].

    Returns:
        The run's files, wall time and peak memory.

    Raises:
        SolverError: If ccx is missing, times out or exits with an error.
        ConvergenceError: If ccx stopped because an increment would not converge.
    """
    exe = find_ccx(executable)
    if exe is None:
        raise SolverError(
            f"CalculiX not found: no {executable!r} on PATH (apt-get install calculix-ccx)"
        )
    job = deck.with_suffix("")
    log = job.with_suffix(".log")
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "CCX_NPROC_EQUATION_SOLVER": str(threads)}
    t0 = time.perf_counter()
    with log.open("w") as out:
        proc = subprocess.Popen(
            [exe, "-i", job.name], cwd=deck.parent, stdout=out, stderr=subprocess.STDOUT, env=env
        )
        rss_mb = _wait(proc, timeout_s, exe)
    wall = time.perf_counter() - t0
    text = log.read_text(errors="replace")
    if "increment size smaller than minimum" in text:
        raise ConvergenceError(
            f"ccx on {deck}: an increment did not converge (see {log})",
            increment=-1,
            iteration=-1,
            residual=float("nan"),
        )
    if proc.returncode != 0 or "*ERROR" in text:
        first = next((ln.strip() for ln in text.splitlines() if "*ERROR" in ln), "")
        raise SolverError(f"ccx on {deck} failed (exit {proc.returncode}): {first} (see {log})")
    return CcxRun(job.with_suffix(".dat"), job.with_suffix(".frd"), log, wall, rss_mb)


def _wait(proc: subprocess.Popen[bytes], timeout_s: float, exe: str) -> float:
    """Wait for ``proc``; return its peak resident memory [MB] (0 if unknown)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        except ChildProcessError:  # already reaped (not by us): memory unknown
            proc.wait()
            return 0.0
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return usage.ru_maxrss / 1024.0  # Linux reports kB
        if time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            raise SolverError(f"{exe} did not finish within {timeout_s:g} s")
        time.sleep(0.05)


@dataclass(frozen=True)
class LoopFigures:
    """The figures two loops are compared by.

    Attributes:
        disp_at_plus_mm: Grip displacement at +Fg at the end of the loop [mm].
        disp_at_minus_mm: Grip displacement at −Fg [mm].
        area_nmm: Area of the closed loop −Fg → +Fg → −Fg, ∮ F dδ [N·mm].
    """

    disp_at_plus_mm: float
    disp_at_minus_mm: float
    area_nmm: float


def loop_figures(
    force_n: FloatArray,
    disp_mm: FloatArray,
    stage: npt.NDArray[np.int64],
    amplitude_n: float,
    *,
    loop_stages: tuple[int, int] = (2, 3),
    free_play_mm: float = 0.0,
) -> LoopFigures:
    """Measure a loop: displacement at ±Fg and the area of the closed loop.

    A stage's points are its own preceded by the last point of the stage before. The
    displacement at ±Fg is interpolated linearly between the last two points of the
    stage that ends there (a penalty model with a grip spring ends a few newtons off Fg).
    The area is the shoelace formula over the points of the two loop stages.

    The free play is taken off every point, half of it toward the side the point is on
    (``sign(δ)``), as our solver removes it: the loop is then the hinge's, and a force
    left at the end of an increment that crossed the free play counts over the motion
    that remains after the removal, not over the whole crossing. (ccx on the 2 mm
    conforming mesh ends the 0.39 mm crossing step 10 µm before the touch with 0.18 N on
    the tang; on the raw points that trapezoid added 0.036 N·mm per crossing, 4.5 times
    our whole loop; docs/calculix_crosscheck.md.)

    Args:
        force_n: Force through the hinge, shape (n,) [N].
        disp_mm: Grip displacement, shape (n,) [mm].
        stage: Stage of each point, shape (n,) int64.
        amplitude_n: Fg [N].
        loop_stages: The stages +Fg → −Fg and −Fg → +Fg.
        free_play_mm: Total free play 4Δr to remove [mm].

    Returns:
        The figures.

    Raises:
        DataError: If a loop stage has no point.
    """
    down, up = loop_stages
    disp_mm = np.asarray(disp_mm, dtype=np.float64)
    if free_play_mm > 0.0:
        disp_mm = disp_mm - np.sign(disp_mm) * free_play_mm / 2.0
    peaks = []
    for s, target in ((up, amplitude_n), (down, -amplitude_n)):
        idx = _with_start(stage, s)
        if len(idx) < 2:
            raise DataError(f"stage {s} has no point; the loop needs stages {loop_stages}")
        (f0, f1), (d0, d1) = force_n[idx[-2:]], disp_mm[idx[-2:]]
        d = d1 if f1 == f0 else d0 + (target - f0) * (d1 - d0) / (f1 - f0)
        peaks.append(float(d))
    idx = np.union1d(_with_start(stage, down), _with_start(stage, up))
    f, d = force_n[idx], disp_mm[idx]
    area = 0.5 * abs(float(np.dot(d, np.roll(f, -1)) - np.dot(f, np.roll(d, -1))))
    return LoopFigures(peaks[0], peaks[1], area)


def _with_start(stage: npt.NDArray[np.int64], s: int) -> npt.NDArray[np.int64]:
    """Indices of stage ``s``'s points, preceded by the point just before the stage."""
    idx = np.flatnonzero(stage == s).astype(np.int64)
    if len(idx) and idx[0] > 0:
        idx = np.concatenate([[idx[0] - 1], idx]).astype(np.int64)
    return idx
