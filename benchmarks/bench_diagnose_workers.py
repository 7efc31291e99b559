"""6-case diagnoses at the default mesh: in process and on 2 workers, coarse to fine or not.

Issue 35, item 2: the wall time of a default-mesh diagnosis, its 1 → 2 worker speed-up and
the width of its task graph (runs per batch).

* ``general``: data from ``hingelab synth`` of the coarse example model (its own, finer data
  mesh; so the default-mesh model is judged on loops of another mesh), Δr 0 and 0.1 mm ×
  Fg 100, 250, 400 N, a hidden frame compliance of 2e-5 mm/N, seed 5. The model: the same
  hinge on the default mesh. Runs: the plain search (``--no-screen``: every grid on the
  default mesh) in process — the reference —, then coarse to fine (the default) in
  process and on 2 workers.
* ``bearing``: the bearing hinge with frictional fits (studies/examples/MODEL_bearing_fits.toml,
  default mesh) on data synthesised from the same model on its coarse preset (and synth's
  finer data mesh from that), F_p 0, 100, 200 N × Fg 150, 400 N, hidden frame compliance
  2e-5 mm/N, seed 5; in process and on 2 workers.

Each run starts from an empty result store (``--out`` of its own) in a fresh process; the
verdict, fitted value and χ² of the runs must agree (the cluster path runs the same code;
the plain search is another path to the same fit).

Wall times on this machine vary by ±10 % between runs of the same code (measured), so
``--repeat N`` runs the in-process and the 2-worker diagnosis N times each, alternating,
and reports the speed-up of the medians (and its range over the pairs); ``--no-plain``
skips the plain search.

``--one-worker`` adds runs on a Dask cluster of one local worker (workers 0 in the table):
the 1/2 worker curve, apart from the in-process run.

Run: .venv/bin/python benchmarks/bench_diagnose_workers.py [general|bearing ...] [--work DIR]
     [--repeat N] [--no-plain] [--one-worker]
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, run_isolated

ROOT = Path(__file__).resolve().parents[1]
HIDDEN = "frame_compliance:compliance_mm_per_n=2e-5"
CASES = {"general": "0:100,250,400;0.1:100,250,400", "bearing": "0:150,400;100:150,400;200:150,400"}
EXAMPLE = {"general": "MODEL.toml", "bearing": "MODEL_bearing_fits.toml"}
ONE_WORKER_CLUSTER = 0
"""``workers`` of a run on a Dask cluster of one local worker (``--one-worker``): the cost of
running as tasks, apart from running on two cores (1 is in process, as ``--workers 1``)."""


def _coarse_model(kind: str, work: str) -> str:
    """The example model file on its kind's coarse preset (the data's source)."""
    if kind == "general":
        return str(ROOT / "studies/examples/MODEL.toml")  # already the coarse preset
    text = (ROOT / "studies/examples" / EXAMPLE[kind]).read_text()
    head, _, tail = text.partition("[mesh]")
    tail = tail[tail.index("[materials.") if "[materials." in tail else tail.index("[friction]") :]
    coarse = (
        "[mesh]\nsize_mm = 4.0\ncontact_size_mm = 0.8\nslave_ratio = 1.5\n"
        '[mesh.part_sizes_mm]\n"ring" = 1.2\n\n'
    )
    path = Path(work, f"MODEL_{kind}_coarse.toml")
    path.write_text(head + coarse + tail)
    return str(path)


def _default_model(kind: str, work: str) -> str:
    """The example model file on the default mesh."""
    if kind == "bearing":
        return str(ROOT / "studies/examples" / EXAMPLE[kind])  # its [mesh] is the default
    text = (ROOT / "studies/examples/MODEL.toml").read_text()
    head, _, tail = text.partition("[mesh]")
    tail = tail[tail.index("[friction]") :]
    model = Path(work, "MODEL_default_mesh.toml")
    model.write_text(head + tail)
    return str(model)


def _synth(work: str, kind: str) -> dict[str, Any]:
    from studies.cli.main import main

    argv = ["synth", _coarse_model(kind, work), "--effect", HIDDEN, "--cases", CASES[kind]]
    assert main([*argv, "--seed", "5", "--out", f"{work}/data_{kind}"]) == 0
    return {}


def _diagnose(
    work: str, kind: str, model: str, workers: int, screen: bool, rep: int = 0
) -> dict[str, Any]:
    import contextlib
    import io

    from studies.cli.main import main

    label = f"{kind}_w{workers}_{'screen' if screen else 'plain'}_{rep}"  # each run from empty
    argv = ["diagnose", model, f"{work}/data_{kind}", "--json", "--out", f"{work}/{label}"]
    argv += [] if screen else ["--no-screen"]
    buf = io.StringIO()
    with contextlib.ExitStack() as stack:
        if workers == ONE_WORKER_CLUSTER:  # a cluster of one worker, started as --workers N's
            from model.cluster import local_cluster

            cluster = stack.enter_context(local_cluster(1))
            argv += ["--scheduler", cluster.scheduler_address]
        else:
            argv += ["--workers", str(workers)]
        stack.enter_context(contextlib.redirect_stdout(buf))
        assert main(argv) == 0
    d = json.loads(buf.getvalue())
    best = d["candidates"][0] if d["candidates"] else {}
    st = d["stats"]
    return {
        "hinge": kind,
        "search": "coarse→fine" if screen else "plain",
        "workers": workers,
        "verdict": d["verdict"],
        "best": best.get("name", ""),
        "value": best.get("value", float("nan")),
        "chi2": best.get("chi2", float("nan")),
        "cycles": st.get("n_cycles", ""),
        "coarse_cycles": st.get("screen_cycles", 0),
        "batches": st.get("batches", ""),
        "widest": st.get("widest_batch", ""),
        "refine_runs": ",".join(str(c.get("refine_runs", "")) for c in d["candidates"]),
        **_cycle_seconds(Path(work, label, "results")),
    }


def _cycle_seconds(results: Path) -> dict[str, float]:
    """The cycles' own time in a run's store: the sum over its results of their timings
    (preload and cycle: what a worker spends in the contact solver), and their count.

    With the wall time it splits a run into the cycles, which spread over the workers, and
    the rest (start-up, each worker's set-up of its geometries, the verdict), which does not
    all spread: the bound on the 1 → 2 worker speed-up the reading below states.
    """
    total, n = 0.0, 0
    for f in sorted(results.glob("*.npz")):
        with np.load(f, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
        total += sum(float(v) for v in meta.get("timings_s", {}).values())
        n += 1
    return {"cycle_sum_s": total, "stored": n}


def main() -> None:
    args = sys.argv[1:]
    work = tempfile.mkdtemp(prefix="bench_diag_w_")
    if "--work" in args:
        i = args.index("--work")
        work = args[i + 1]
        del args[i : i + 2]
    repeat = 1
    if "--repeat" in args:
        i = args.index("--repeat")
        repeat = int(args[i + 1])
        del args[i : i + 2]
    plain = "--no-plain" not in args
    one_worker = "--one-worker" in args
    args = [a for a in args if a not in ("--no-plain", "--one-worker")]
    kinds = args or ["general", "bearing"]
    os.makedirs(work, exist_ok=True)
    print(f"work folder {work}; load average {os.getloadavg()}")
    for kind in kinds:
        if not Path(work, f"data_{kind}", "cases.csv").is_file():
            run_isolated(_synth, work, kind)
        model = _default_model(kind, work)
        runs = [(w, True, r) for r in range(repeat) for w in (1, 2)]
        if kind == "general" and plain:
            runs = [(1, False, 0), *runs]
        if one_worker:
            runs += [(ONE_WORKER_CLUSTER, True, r) for r in range(repeat)]
        rows = [run_isolated(_diagnose, work, kind, model, w, sc, r) for w, sc, r in runs]
        cols = ["hinge", "search", "workers", "wall_s", "peak_MB", "cycles", "coarse_cycles"]
        cols += ["batches", "widest", "refine_runs", "stored", "cycle_sum_s"]
        cols += ["verdict", "best", "value", "chi2"]
        print_table(rows, cols)
        one = [r for r in rows if r["workers"] == 1 and r["search"] != "plain"][-1]
        ones = [r["wall_s"] for r in rows if r["workers"] == 1 and r["search"] != "plain"]
        twos = [r["wall_s"] for r in rows if r["workers"] == 2]
        pairs = [a / b for a, b in zip(ones, twos, strict=True)]
        med1, med2 = float(np.median(ones)), float(np.median(twos))
        print(
            f"{kind}: speed-up 1 → 2 workers: {med1 / med2:.2f}× (medians {med1:.1f} s / "
            f"{med2:.1f} s over {len(ones)} run(s) each; pairs {min(pairs):.2f}–{max(pairs):.2f}×)"
        )
        same = all(
            r["verdict"] == rows[0]["verdict"] and r["best"] == rows[0]["best"] for r in rows
        )
        screened = [r for r in rows if r["search"] != "plain"]
        rel = max(abs(r[k] / one[k] - 1.0) for r in screened for k in ("value", "chi2"))
        print(
            f"{kind}: same verdict and effect in every run: {same}; in process, on 1 and 2 "
            f"workers: value and χ² agree to {rel:.1e} relative"
        )
        if kind == "general" and plain:
            ref = rows[0]
            print(
                f"general: coarse→fine vs plain: value {one['value'] / ref['value'] - 1:+.2%}, "
                f"χ² {one['chi2']:.3g} vs {ref['chi2']:.3g}; "
                f"{ref['wall_s'] / one['wall_s']:.2f}× faster in process"
            )
        cl = [r["wall_s"] for r in rows if r["workers"] == ONE_WORKER_CLUSTER]
        if cl:
            med_c = float(np.median(cl))
            print(
                f"{kind}: one-worker cluster {med_c:.1f} s: {med_c / med1:.2f}× the in-process "
                f"time; 2 workers {med_c / med2:.2f}× faster than one"
            )
        print(f"load average after: {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
