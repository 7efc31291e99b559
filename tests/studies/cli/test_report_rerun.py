"""A study rerun into its folder with another μ: no page, plot or table shows another run's files.

The probe of issue 33: run a study, change μ in the study file, rerun into the same folder,
then ``report`` and ``trace``. It runs on the plug-in kind ``jenkins_pin`` (no mesh, no FE;
the loop picture's title names μ, so the two runs' pictures differ).
"""

from __future__ import annotations

import base64
import hashlib
import json
import shlex
from html.parser import HTMLParser
from pathlib import Path

import pytest

from rsm import trace
from studies.cli.main import main

MODEL = '[hinge]\nkind = "jenkins_pin"\n[cycle]\nincrements_per_stage = 8\n'
STUDY = """[study]
name = "rerun"
model = "MODEL.toml"
[solver]
mu = {mu}
[design]
type = "full_factorial"
[design.slip_force_N]
levels = [30.0]
[design.amplitude_N]
levels = [200.0, 400.0]
"""


class _Figures(HTMLParser):
    """The page's figures (alt text → PNG bytes), its table headers and its text."""

    def __init__(self) -> None:
        super().__init__()
        self.figures: dict[str, bytes] = {}
        self.heads: list[str] = []
        self.text: list[str] = []
        self._in_th = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.figures[a["alt"]] = base64.b64decode(a["src"].split(",", 1)[1])
        self._in_th = tag == "th"

    def handle_endtag(self, tag):
        self._in_th = False

    def handle_data(self, data):
        self.text.append(data)
        if self._in_th:
            self.heads.append(data)


def _page(path: Path) -> _Figures:
    page = _Figures()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _run_twice(tmp_path: Path) -> tuple[Path, list[list[str]]]:
    (tmp_path / "MODEL.toml").write_text(MODEL)
    study, out = tmp_path / "STUDY.toml", tmp_path / "out"
    argvs = []
    for mu in (0.2, 0.25):
        study.write_text(STUDY.format(mu=mu))
        argv = ["study", str(study), "--out", str(out), "--no-plots", "--json"]
        assert main(argv) == 0
        argvs.append(argv)
    return out, argvs


@pytest.fixture
def rerun(jenkins, tmp_path, capsys):  # type: ignore[no-untyped-def]
    out, argvs = _run_twice(tmp_path)
    capsys.readouterr()
    return out, argvs


def test_the_first_runs_files_survive_the_rerun(rerun) -> None:  # type: ignore[no-untyped-def]
    out, _ = rerun
    walked = [trace.walk(out / "trace.sqlite", pid) for pid in (1, 2, 3, 4)]
    assert [w.solver["mu"] for w in walked] == [0.2, 0.2, 0.25, 0.25]
    for w in walked:
        bad = [a.message for a in w.artifacts if a.state is not trace.ArtifactState.OK]
        assert bad == [], f"point {w.point_id}: {bad}"
        kinds = {a.kind for a in w.artifacts}
        assert {"loop_csv", "loop_png", "result_json"} <= kinds
        manifest = json.loads(
            next(a.path for a in w.artifacts if a.kind == "result_json").read_text()
        )
        assert manifest["solver"]["result_key"] == w.solver["result_key"]
    assert len(list((out / "points").iterdir())) == 4  # two points × two μ, none shared


def test_report_shows_each_point_only_its_own_loop_and_a_mu_column(rerun) -> None:  # type: ignore[no-untyped-def]
    out, argvs = rerun
    assert main(["report", str(out)]) == 0
    page = _page(out / "report.html")
    loops = {alt: png for alt, png in page.figures.items() if alt.startswith("point ")}
    assert len(loops) == 4
    for pid in (1, 2, 3, 4):
        w = trace.walk(out / "trace.sqlite", pid)
        recorded = next(a.sha256 for a in w.artifacts if a.kind == "loop_png")
        (png,) = [v for k, v in loops.items() if k.startswith(f"point {pid}:")]
        assert hashlib.sha256(png).hexdigest() == recorded, f"point {pid} shows another run's loop"
        caption = next(k for k in loops if k.startswith(f"point {pid}:"))
        assert caption.endswith(f"μ = {w.solver['mu']:g}")
    assert "μ" in page.heads  # the setting that differs is a column
    text = " ".join(page.text)
    assert "settings that differ between the points" in text
    assert "friction coefficient μ" not in text  # not in the header as if all points had one μ
    # the command rows are the two command lines that ran, not a template
    assert shlex.join(["hingelab", *argvs[1]]) in text
    assert text.count(shlex.join(["hingelab", *argvs[0]])) == 2  # the same line, run twice


def test_report_refuses_to_show_a_replaced_file_under_a_points_name(tmp_path) -> None:
    """A folder of an older hingelab, whose point folder a rerun overwrote in place."""
    from rsm import trace_store
    from studies.report.page import build_report

    loop = tmp_path / "points" / "c0.000_F200" / "loop.png"
    loop.parent.mkdir(parents=True)
    first = _tiny_png(1)
    loop.write_bytes(first)
    trace_store.record_point(
        tmp_path / "trace.sqlite",
        study="old",
        params={"clearance_mm": 0.0, "amplitude_N": 200.0},
        artifacts={"loop_png": loop},
        solver={"mu": 0.2},
        results={"eta": 0.0143},
    )
    loop.write_bytes(_tiny_png(2))  # a later run with another μ wrote its loop here
    html = build_report(tmp_path, tmp_path)
    page = _Figures()
    page.feed(html)
    assert not any(alt.startswith("point 1") for alt in page.figures)
    assert "point 1 (replaced by another run)" in html
    assert "loop.png: replaced by another run" in html
    assert 'href="points/c0.000_F200/loop.png"' not in html
    loop.write_bytes(first)  # the recorded content again (another mtime): shown
    page = _Figures()
    page.feed(build_report(tmp_path, tmp_path))
    assert [v for k, v in page.figures.items() if k.startswith("point 1:")] == [first]


def _tiny_png(shade: int) -> bytes:
    import io

    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(1.0, 1.0), dpi=20, facecolor=(shade / 3, 0.5, 0.5))
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
