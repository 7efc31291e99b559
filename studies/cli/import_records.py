"""``hingelab import-records``: a test rig's record files → a measurement folder.

``hingelab import-records MAPPING.toml SOURCE... --out DIR [--yardstick CONDITION]
[--x COLUMN] [--json]`` reads each record file (or each folder's files matching the
mapping's ``source.glob``) through the mapping (``validation.rig_mapping``), converts to
mm, N, s, splits displacement-controlled records into their steady cycles and writes
``cases.csv``, ``loops/*.csv`` and ``import.json`` into DIR (``validation.rig_import``).
``--yardstick band_tension_N`` also prints the energy per cycle of every record, its
cycle-to-cycle scatter and the straight line's leave-one-amplitude-out error
(``validation.rig_yardstick``), and writes them to ``DIR/yardstick.json``. A bad record
stops the import with one line naming the file, the column and the problem; nothing is
written then.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``import-records`` subcommand."""
    p = sub.add_parser(
        "import-records",
        help="read a test rig's files through a mapping (rig.toml) into a measurement folder",
    )
    p.add_argument("mapping", type=Path, metavar="MAPPING.toml", help="the rig's mapping file")
    p.add_argument(
        "sources", type=Path, nargs="+", metavar="SOURCE", help="record files or folders"
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="new measurement folder")
    p.add_argument(
        "--yardstick",
        metavar="CONDITION",
        default=None,
        help="also report energy per cycle and the straight-line leave-one-amplitude-out "
        "error, one line per level of CONDITION (e.g. band_tension_N; default: not reported)",
    )
    p.add_argument(
        "--x",
        default="amplitude_mm",
        metavar="COLUMN",
        help="amplitude of the yardstick's line: amplitude_mm (measured, default) or a "
        "condition such as nominal_amplitude_mm",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab import-records``."""
    from model.jsonio import dumps
    from validation.rig_import import import_records
    from validation.rig_mapping import read_mapping

    mapping = read_mapping(args.mapping)
    mset, done = import_records(mapping, args.sources, args.out)
    summary: dict[str, Any] = {
        "out": str(args.out),
        "records": len(done),
        "cases": len(mset.cases),
        "per_record": {
            str(r.record.path.name): {
                "cases": len(r.case_ids),
                "cycles": 0 if r.split is None else int(r.split.peak_to_peak_mm.size),
            }
            for r in done
        },
    }
    text = None
    if args.yardstick is not None:
        from validation.rig_yardstick import energy_yardstick, format_yardstick

        y = energy_yardstick(mset, args.yardstick, args.x)
        summary["yardstick"] = _yardstick_json(y)
        (args.out / "yardstick.json").write_text(dumps(summary["yardstick"]) + "\n", "utf-8")
        text = format_yardstick(y)
    if args.json:
        print(dumps(summary))
        return 0
    print(
        f"{summary['records']} record(s) → {summary['cases']} case(s) in {args.out} "
        "(cases.csv, loops/, import.json)"
    )
    if text is not None:
        print(text)
    return 0


def _yardstick_json(y: Any) -> dict[str, Any]:
    loo = {id(r.record): r for r in y.rows}
    records = []
    for r in y.records:
        row = loo.get(id(r))
        records.append(
            {
                "cases": list(r.case_ids),
                y.by: r.group,
                y.x: r.x,
                "energy_per_cycle_Nmm": [float(e) for e in r.energies_nmm],
                "mean_Nmm": r.mean_nmm,
                "scatter": r.scatter,
                "line_prediction_Nmm": None if row is None else row.predicted_nmm,
                "line_error": None if row is None else row.error,
            }
        )
    return {
        "by": y.by,
        "x": y.x,
        "rms_error": y.rms_error,
        "max_scatter": y.max_scatter,
        "records": records,
    }
