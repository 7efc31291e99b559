"""One self-contained HTML page for a result folder (``hingelab report``).

The kind of folder is recognised by its files (:data:`SIGNATURES`): a load cycle
(``hingelab cycle``), a sweep (``hingelab sweep``, with the plots of an ``rsm fit`` when
present), a paper validation (``python -m studies.paper.validation``), the paper's
surfaces refitted (``hingelab rsm paper``), a comparison (``hingelab compare``), a
calibration (``hingelab calibrate``) or a repeatability analysis (``hingelab
repeatability``). Its "command" row is the command line that wrote the folder, as
recorded there (``commands.jsonl``, ``studies.outputs.record_command``). The page embeds every figure as a base64 PNG
``data:`` URI and its style sheet inline; it loads nothing from the network and needs
no script. Links to result files (STEP, VTU, loop CSV, …) are relative to the page.

>>> from pathlib import Path
>>> detect_kind(Path("no/such/folder"))  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
cad.errors.DataError: no/such/folder: no such folder; expected one of: cycle: result.json + ...
"""

from __future__ import annotations

import datetime as dt
import platform
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

from cad.errors import DataError
from model.code import ALL_PACKAGES, code_version
from studies.outputs import recorded_commands
from studies.report.paper import paper_study_report
from studies.report.parts import CSS, Html, esc, join, kv_table, tag
from studies.report.repeatability import repeatability_report
from studies.report.sections import ReportBody, cycle_report
from studies.report.sweep import sweep_report
from studies.report.validation import (
    calibrate_report,
    compare_report,
    paper_validation_report,
    rsm_paper_report,
)


class ReportKind(Enum):
    """The kinds of result folder a report can be made for."""

    CYCLE = "cycle"
    SWEEP = "sweep"
    PAPER_STUDY = "paper study"
    PAPER_VALIDATION = "paper validation"
    RSM_PAPER = "rsm paper"
    CALIBRATE = "calibrate"
    COMPARE = "compare"
    REPEATABILITY = "repeatability"


SIGNATURES: dict[ReportKind, tuple[str, ...]] = {
    ReportKind.CYCLE: ("result.json", "loop.csv"),
    ReportKind.SWEEP: ("trace.sqlite",),
    ReportKind.PAPER_STUDY: ("report.json", "modified", "general"),
    ReportKind.PAPER_VALIDATION: ("report.json", "compare_table1"),
    ReportKind.RSM_PAPER: ("paper_comparison.json",),
    ReportKind.CALIBRATE: ("ledger.json",),
    ReportKind.COMPARE: ("comparison.json",),
    ReportKind.REPEATABILITY: ("repeatability.json",),
}
"""The files (or folders) that identify each kind, checked in this order."""

_BUILDERS: dict[ReportKind, Callable[[Path, Path], ReportBody]] = {
    ReportKind.CYCLE: cycle_report,
    ReportKind.SWEEP: sweep_report,
    ReportKind.PAPER_STUDY: paper_study_report,
    ReportKind.PAPER_VALIDATION: paper_validation_report,
    ReportKind.RSM_PAPER: rsm_paper_report,
    ReportKind.CALIBRATE: calibrate_report,
    ReportKind.COMPARE: compare_report,
    ReportKind.REPEATABILITY: repeatability_report,
}

_MAIN_FILE = {kind: names[0] for kind, names in SIGNATURES.items()}


@dataclass(frozen=True)
class ReportMeta:
    """Where and when the page was made.

    Attributes:
        version: hingelab's version and source digest (``model.code.CodeVersion.short``)
            of the code that made the page.
        generated_utc: When the page was made (ISO 8601, UTC).
        run_utc: When the folder's main result file was last written (ISO 8601, UTC).
    """

    version: str
    generated_utc: str
    run_utc: str


def expected_files() -> str:
    """Return the identifying files of every kind, as one line."""
    return "; ".join(f"{k.value}: {' + '.join(names)}" for k, names in SIGNATURES.items())


def detect_kind(folder: Path) -> ReportKind:
    """Return the kind of result folder from the files it holds.

    Raises:
        DataError: Naming the folder and the files expected, if no kind matches.
    """
    if folder.is_dir():
        for kind, names in SIGNATURES.items():
            if all((folder / n).exists() for n in names):
                return kind
    what = "not a hingelab result folder" if folder.is_dir() else "no such folder"
    if not folder.is_dir() and folder.exists():
        what = "not a folder"
    raise DataError(f"{folder}: {what}; expected one of: {expected_files()}")


def _utc(ts: float | None = None) -> str:
    t = dt.datetime.now(dt.UTC) if ts is None else dt.datetime.fromtimestamp(ts, dt.UTC)
    return t.replace(microsecond=0).isoformat().replace("+00:00", "Z")


def report_meta(folder: Path, kind: ReportKind) -> ReportMeta:
    """Return the version, the time now and the time the folder's main file was written."""
    main = folder / _MAIN_FILE[kind]
    return ReportMeta(code_version(ALL_PACKAGES).short(), _utc(), _utc(main.stat().st_mtime))


def command_rows(folder: Path, made_by: str) -> list[tuple[str, object]]:
    """The "command" rows: the command lines recorded in the folder, or that none was.

    Args:
        folder: The result folder.
        made_by: What kind of command makes such a folder (shown when none was recorded).
    """
    records = recorded_commands(folder)
    if not records:
        return [
            (
                "command",
                "not recorded in this folder (written by a hingelab older than its "
                f"commands.jsonl); folders of this kind are made by: {made_by}",
            )
        ]
    ok = [r for r in records if r.get("exit_status") == 0]
    last = (ok or records)[-1]
    rows: list[tuple[str, object]] = [
        ("command", last["command"]),
        ("run in", last.get("cwd", "—")),
        ("ended", f"{last.get('ended_utc', '—')}, exit status {last.get('exit_status', '—')}"),
    ]
    others = [r for r in records if r is not last]
    if others:
        rows.append(
            (
                "other commands in this folder",
                tag(
                    "ul",
                    join(
                        tag("li", f"{r['command']} ({r.get('ended_utc', '—')}, "
                                  f"exit status {r.get('exit_status', '—')})")
                        for r in others
                    ),
                ),
            )
        )  # fmt: skip
    return rows


def _with_commands(folder: Path, run: list[tuple[str, object]]) -> list[tuple[str, object]]:
    """``run`` with its "command" row (what makes such a folder) replaced by the real one."""
    made_by = next((str(v) for k, v in run if k == "command"), "hingelab")
    rows = command_rows(folder, made_by)
    out = [r for r in run if r[0] != "command"]
    at = next((i for i, r in enumerate(run) if r[0] == "command"), 0)
    return out[:at] + rows + out[at:]


def render_html(folder: Path, kind: ReportKind, body: ReportBody, meta: ReportMeta) -> str:
    """Assemble the page: header, what was run, table of contents, sections, footer."""
    run = [
        ("result folder", str(folder)),
        ("kind", f"{kind.value} (recognised by {' + '.join(SIGNATURES[kind])})"),
        *_with_commands(folder, body.run),
        ("results written", meta.run_utc),
        ("report made", f"{meta.generated_utc} with hingelab {meta.version}"),
    ]
    toc = tag(
        "nav",
        join(
            [tag("a", "What was run", href="#run")]
            + [tag("a", s.title, href=f"#{_anchor(s.anchor)}") for s in body.sections]
        ),
        cls="toc",
    )
    sections = join(
        tag("section", join([tag("h2", s.title), s.body]), id=_anchor(s.anchor))
        for s in body.sections
    )
    header = tag(
        "header",
        join(
            [
                tag("h1", f"hingelab report — {body.title}"),
                tag("p", str(folder), cls="sub"),
                toc,
            ]
        ),
        cls="top",
    )
    footer = tag(
        "footer",
        f"hingelab {meta.version} · Python {platform.python_version()} · units mm, N, MPa, s · "
        f"generated {meta.generated_utc}",
    )
    run_section = tag("section", join([tag("h2", "What was run"), kv_table(run)]), id="run")
    page = join([header, run_section, sections, footer])
    title = esc(f"hingelab report — {body.title} — {folder.name}")
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{title}</title>\n<style>{CSS}</style>\n</head>\n"
        f"<body>\n<main>\n{Html(page)}\n</main>\n</body>\n</html>\n"
    )


def _anchor(text: str) -> str:
    return "".join(ch if ch.isalnum() else "-" for ch in text.lower()).strip("-")


def build_report(folder: Path, report_dir: Path) -> str:
    """Return the HTML page for a result folder.

    Args:
        folder: The result folder.
        report_dir: The folder the page will be written to (links are relative to it).

    Raises:
        DataError: Naming the folder or file, if the folder is not a result folder or a
            result file cannot be read.
    """
    kind = detect_kind(folder)
    try:
        body = _BUILDERS[kind](folder, report_dir)
    except (KeyError, TypeError, AttributeError) as err:  # a result file of another shape
        raise DataError(
            f"{folder / _MAIN_FILE[kind]}: unexpected content for a {kind.value} folder "
            f"({type(err).__name__}: {err})"
        ) from err
    return render_html(folder, kind, body, report_meta(folder, kind))


def write_report(folder: Path, out: Path) -> Path:
    """Write the HTML page for a result folder to ``out``; return ``out``.

    Raises:
        DataError: As :func:`build_report`.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    text = build_report(folder, out.parent)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(out)
    return out
