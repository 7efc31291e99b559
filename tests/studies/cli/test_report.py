"""``hingelab report``: one self-contained HTML page, checked by structure and in headless Chromium.

Structure: every ``<img>`` is a ``data:image/png`` URI that decodes to a picture, every
``href`` is an in-page anchor or a relative link to a file that exists, nothing points to the
network, no script, text escaped. Rendering: Chromium (Debian ``chromium``; installed with apt
when missing and we are root, else the rendering tests skip and say why) takes a screenshot,
whose first figure must show non-blank pixels, and loads a copy of the page with a checking
script appended (test-only; the report itself has no script), which must find every image
decoded and log no console message.
"""

from __future__ import annotations

import base64
import io
import json
import os
import shlex
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
import pytest

from studies.cli.main import main

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
FIGURE_RGB = (0.12, 0.62, 0.54)
"""Face colour of the synthetic loop picture: the screenshot test looks for it."""

CHECK_SCRIPT = """<script>
window.addEventListener('load', () => {
  const bad = [...document.images].filter(i => !(i.complete && i.naturalWidth > 0))
    .map(i => i.alt || i.src.slice(0, 40));
  document.documentElement.setAttribute('data-images', document.images.length);
  document.documentElement.setAttribute('data-broken', JSON.stringify(bad));
  if (bad.length) console.error('broken images: ' + bad.join(', '));
});
</script>"""


@pytest.fixture(autouse=True)
def _report_registered(monkeypatch):
    """Register the subcommand if studies/cli/main.py does not list it yet."""
    import studies.cli.main

    if "studies.cli.report" not in studies.cli.main.SUBCOMMAND_MODULES:
        monkeypatch.setattr(
            studies.cli.main,
            "SUBCOMMAND_MODULES",
            (*studies.cli.main.SUBCOMMAND_MODULES, "studies.cli.report"),
        )


# ---------------------------------------------------------------- synthetic folders


def _png(path: Path, *, face=FIGURE_RGB, size=(6.0, 4.0)) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=size, dpi=100, facecolor=face)
    ax.set_facecolor(face)
    t = np.linspace(0, 2 * np.pi, 60)
    ax.plot(np.sin(t) * 3e-3, 400 * np.sin(t + 0.3), color="black", lw=2)
    ax.set_xlabel("δ [mm]")
    ax.set_ylabel("F [N]")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, facecolor=face)
    plt.close(fig)
    return path


def _cycle_folder(root: Path) -> Path:
    """A folder shaped like ``hingelab cycle --out`` writes it (tiny files, real PNGs)."""
    d = root / "cycle"
    _png(d / "loop.png")
    _png(d / "mesh.png", face=(0.9, 0.85, 0.7), size=(8.0, 3.5))
    (d / "loop.csv").write_text("force_N,displacement_mm,stage,increment\n0,0,0,0\n")
    (d / "hinge.step").write_text("ISO-10303-21;\nEND-ISO-10303-21;\n")
    (d / "mesh.vtu").write_text("<VTKFile/>\n")
    (d / "fields").mkdir()
    (d / "fields" / "cycle.pvd").write_text("<VTKFile/>\n")
    incs = [
        {"stage": s, "force_N": f, "disp_mm": f * 1e-5, "iterations": 3}
        | {"open": 10, "stick": 5, "slip": 3}
        for s, f in ((0, 200.0), (0, 400.0), (1, 0.0), (1, -400.0), (2, 400.0))
    ]
    result = {
        "eta": 0.014341,
        "W_cycle_Nmm": 0.0578529,
        "U_max_Nmm": 0.642043,
        "delta_max_mm": 0.00321,
        "disp_at_peak_mm": 0.0039186,
        "disp_at_minus_peak_mm": -0.0025018,
        "secant_stiffness_N_per_mm": 124602.29,
        "free_play_mm": 0.0,
        "friction_work_Nmm": 0.0577209,
        "elastic_energy_change_Nmm": 0.000132,
        "energy_balance_rel_err": 1.2e-14,
        "W_change_last_two_cycles_rel": None,
        "delta_definition": "δ_max = (δ(+Fg) − δ(−Fg))/2 <script>alert(1)</script> & <b>co</b>",
        "amplitude_N": 400.0,
        "mu": 0.2,
        "clearance_mm": 0.0,
        "n_dof": 12747,
        "n_hex": 3080,
        "n_contact_pairs": 408,
        "n_surface_pairs": 3,
        "increments": incs,
        "total_iterations": 15,
        "timings_s": {"mesh": 0.1, "contact": 2.3},
        "files": {},
        "wall_s": 11.6,
    }
    (d / "result.json").write_text(json.dumps(result))
    return d


def _compare_json(cases=("c200", "c300_bad")) -> dict:
    def case(cid):
        bad = cid.endswith("bad")
        return {
            "case_id": cid,
            "clearance_mm": 0.0,
            "amplitude_N": 200.0,
            "passed": not bad,
            "failed": ["disp_at_peak_mm"] if bad else [],
            "errors": {"disp_at_peak_mm": -0.23 if bad else 0.001, "eta": 0.004},
            "measured": {"eta": 0.0145},
            "model": {"eta": 0.0143},
            "source": None,
        }

    return {
        "model_file": "MODEL.toml",
        "data": "data",
        "settings": {"k": 2.0, "default_rel_uncertainty": 0.05},
        "summary": {
            "n_cases": 2,
            "n_pass": 1,
            "metrics": {"eta": {"n": 2, "bias": 0.004, "rms": 0.004, "max_abs": 0.004}},
        },
        "cases": [case(c) for c in cases],
        "fingerprint": [{"group": "general", "slope_W_measured": 2.02, "slope_W_model": 2.0}],
        "model_loop_free_play": True,
        "wall_s": 7.9,
    }


def _other_folders(root: Path) -> dict[str, Path]:
    """One minimal folder of each other kind (JSON of the right shape, real PNGs)."""
    out = {}
    d = out["compare"] = root / "compare"
    _png(d / "error_map.png")
    _png(d / "loops" / "c200.png")
    (d / "comparison.json").write_text(json.dumps(_compare_json()))
    d = out["calibrate"] = root / "calibrate"
    ledger = [{"step": "baseline", "params": {}, "n_params": 0, "chi2": 141.5, "error": 3.97}]
    _png(d / "ledger.png")
    (d / "compare").mkdir(parents=True)
    (d / "ledger.json").write_text(json.dumps(ledger))
    (d / "MODEL.toml").write_text('[hinge]\nkind = "general"\n')
    (d / "compare" / "comparison.json").write_text(json.dumps(_compare_json()))
    d = out["rsm paper"] = root / "rsm_paper"
    _png(d / "general_contour.png")
    hinge = {"x_names": ["clearance_mm", "amplitude_N"], "terms": ["1"], "coefficients": [0.1]}
    hinge |= {"metrics": {"R2": 0.9996}, "minimum": {"x": [0.4, 100.0], "eta": 0.035}}
    hinge |= {"eta_below_0.05": {"lower": [0.16, 100], "upper": [0.4, 119], "area_fraction": 0.016}}
    paper = {"checks": [], "n_checks": 144, "n_reproduced": 138, "general": hinge}
    (d / "paper_comparison.json").write_text(json.dumps(paper))
    d = out["paper validation"] = root / "paper_validation"
    _png(d / "compare_table1" / "error_map.png")
    (d / "compare_table1" / "comparison.json").write_text(json.dumps(_compare_json(("row1",))))
    case = {"clearance_mm": 0.0, "amplitude_N": 100.0, "eta_paper": 0.0656, "eta_model": 0.0146}
    diag = {"verdict": "effect_missing", "message": "face_friction is missing", "candidates": []}
    report = {
        "model": {"mesh": {"size_mm": 4.0}, "mu": 0.2},
        "compare_table1": {"cases": [case | {"eta_error": -0.78}]},
        "diagnose_zero_clearance": diag,
    }
    (d / "report.json").write_text(json.dumps(report))
    out["sweep"] = _sweep_folder(root / "sweep")
    d = out["study"] = _sweep_folder(root / "study")
    (d / "study.toml").write_text('[study]\nname = "demo"\n')
    region = {"threshold": 0.005, "below": True, "x": ["clearance_mm", "amplitude_N"]}
    region |= {"fixed": {}, "area_fraction": 0.2859, "n_parts": 1}
    region |= {"lower": [0.07, 200.0], "upper": [0.1, 400.0]}
    fit = {"x": ["clearance_mm", "amplitude_N"], "y": "eta", "degree": 1, "n_points": 4}
    fit |= {"metrics": {"R2": 0.999}, "minimum": {"x": [0.1, 200.0], "y": 0.00108}}
    fit |= {"threshold_region": region, "warnings": ["looks <over-fitted>"]}
    _png(d / "rsm" / "contour.png")
    (d / "rsm" / "fit.json").write_text(json.dumps(fit))
    return out


def _sweep_folder(d: Path) -> Path:
    """A sweep's layout: one point in the trace, its loop picture and STEP file."""
    from rsm import trace_store

    loop = _png(d / "points" / "c0.000_F200" / "loop.png")
    step = d / "geometry" / "c0.000" / "hinge.step"
    step.parent.mkdir(parents=True)
    step.write_text("ISO-10303-21;\n")
    trace_store.record_point(
        d / "trace.sqlite",
        study="demo",
        params={"clearance_mm": 0.0, "amplitude_N": 200.0},
        artifacts={"step": step, "loop_png": loop},
        solver={"mu": 0.2, "mesh": {"size_mm": 4.0}},
        results={"eta": 0.0143},
    )
    return d


# ---------------------------------------------------------------- structure checks


class _Page(HTMLParser):
    """Collect the tags, their src/href attributes and the text of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[str] = []
        self.imgs: list[str] = []
        self.hrefs: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.imgs.append(a.get("src") or "")
        for key in ("href", "src"):
            if key in a and tag != "img":
                self.hrefs.append(a[key] or "")

    def handle_data(self, data):
        self.text.append(data)


def check_structure(page_path: Path) -> _Page:
    """Assert the page is self-contained; return what it holds."""
    import matplotlib.image as mpimg

    text = page_path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    assert text.startswith("<!DOCTYPE html>")
    assert "script" not in page.tags
    assert "link" not in page.tags  # no external style sheet
    assert "url(" not in text  # nor CSS fetching anything
    assert page.imgs, "the page shows no figure"
    prefix = "data:image/png;base64,"
    for src in page.imgs:
        assert src.startswith(prefix), src[:60]
        data = base64.b64decode(src[len(prefix) :], validate=True)
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        assert mpimg.imread(io.BytesIO(data), format="png").size > 0  # decodes in full
    ids = set()
    for h in page.hrefs:
        url = urlparse(h)
        assert not url.scheme, f"external or absolute link: {h}"
        assert not url.netloc, f"external link: {h}"
        if h.startswith("#"):
            ids.add(h[1:])
            continue
        assert not h.startswith("/"), h
        assert (page_path.parent / unquote(url.path)).exists(), f"link to a missing file: {h}"
    for anchor in ids:
        assert f'id="{anchor}"' in text, f"table of contents points to no section: #{anchor}"
    return page


# ---------------------------------------------------------------- Chromium


@pytest.fixture(scope="session")
def chromium():
    """The chromium executable, else skip with the command that installs it (no installs here)."""
    exe = shutil.which("chromium")
    if exe is None:
        pytest.skip("chromium is not installed: run `make peers` (needs root) to install it")
    return exe


def _run_chromium(exe: str, tmp: Path, page: Path, *args: str) -> subprocess.CompletedProcess:
    profile = tmp / f"profile-{len(list(tmp.glob('profile-*')))}"
    cmd = [exe, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--enable-logging=stderr"]
    cmd += ["--v=0", "--log-level=0", *args, page.resolve().as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stderr[-2000:]
    return r


def _console_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


def render_and_check(exe: str, page: Path, tmp: Path, region=None) -> np.ndarray:
    """Screenshot the page and check it in Chromium; return the screenshot (rows, cols, rgb).

    Args:
        exe: chromium.
        page: The report.
        tmp: Scratch folder.
        region: (row0, row1, col0, col1) where the first figure is; None: find the figure by
            the synthetic face colour.
    """
    import matplotlib.image as mpimg

    shot = tmp / f"{page.stem}.png"
    r = _run_chromium(exe, tmp, page, f"--screenshot={shot}", "--window-size=1280,2000")
    assert _console_lines(r.stderr) == []
    img = mpimg.imread(shot)[..., :3]
    assert img.shape[:2] == (2000, 1280)
    if region is None:
        close = np.all(np.abs(img - np.array(FIGURE_RGB)) < 0.03, axis=2)
        assert close.sum() > 20_000, "the first figure is not on the screenshot"
        rows, cols = np.nonzero(close)
        region = (rows.min(), rows.max() + 1, cols.min(), cols.max() + 1)
    r0, r1, c0, c1 = region
    box = img[r0:r1, c0:c1]
    assert box.std() > 0.05, f"blank figure region {region}: std {box.std():.3f}"
    assert np.mean(np.all(box > 0.97, axis=2)) < 0.97, "the figure region is white"
    # the same page with a checking script appended, next to it (relative links resolve)
    harness = page.with_name(f"_check_{page.name}")
    harness.write_text(
        page.read_text(encoding="utf-8").replace("</body>", CHECK_SCRIPT + "</body>")
    )
    try:
        r = _run_chromium(exe, tmp, harness, "--virtual-time-budget=10000", "--dump-dom")
    finally:
        harness.unlink()
    n_img = page.read_text(encoding="utf-8").count("<img ")
    assert f'data-images="{n_img}"' in r.stdout
    assert 'data-broken="[]"' in r.stdout, r.stdout[:300]
    assert _console_lines(r.stderr) == []
    return img


# ---------------------------------------------------------------- tests


def test_report_of_a_cycle_is_self_contained_and_escaped(tmp_path, capsys):
    folder = _cycle_folder(tmp_path)
    out = tmp_path / "reports" / "report.html"
    assert main(["report", str(folder), "--out", str(out)]) == 0
    assert "report.html" in capsys.readouterr().out
    page = check_structure(out)
    html_text = out.read_text(encoding="utf-8")
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; &lt;b&gt;co&lt;/b&gt;" in html_text
    text = " ".join(page.text)
    for expected in ("Load cycle", "0.01434", "Energy balance", "1.2e-14", "124602", "hingelab"):
        assert expected in text, expected
    assert len(page.imgs) == 2  # loop and mesh
    hrefs = set(page.hrefs)  # relative to the report's folder, which is elsewhere
    assert {"../cycle/hinge.step", "../cycle/mesh.vtu", "../cycle/fields/cycle.pvd"} <= hrefs
    assert "@media print" in html_text


@pytest.mark.parametrize(
    ("kind", "expected"),
    [
        ("sweep", ["Design sweep", "Trace", "0.0143"]),
        (
            "study",
            ["Design study", "Study file", "eta < 0.005 on 28.6 % of the box", "<over-fitted>"],
        ),
        ("compare", ["Comparison table", "FAIL", "-23.0 %", "Errors per metric"]),
        ("calibrate", ["Error ledger", "Calibrated model", "141.5"]),
        ("rsm paper", ["138 / 144", "eta_below_0.05", "1.6 %"]),
        ("paper validation", ["effect_missing", "-78 %", "0.0656"]),
    ],
    ids=["sweep", "study", "compare", "calibrate", "rsm-paper", "paper-validation"],
)
def test_report_of_each_kind(tmp_path, kind, expected):
    folder = _other_folders(tmp_path)[kind]
    out = folder / "report.html"
    assert main(["report", str(folder)]) == 0
    page = check_structure(out)
    text = " ".join(page.text)
    assert "recognised by" in text
    for e in expected:
        assert e in text, e


def test_sweep_links_each_point_files(tmp_path):
    folder = _other_folders(tmp_path)["sweep"]
    out = folder / "report.html"
    assert main(["report", str(folder), "--out", str(out)]) == 0
    page = check_structure(out)
    assert "geometry/c0.000/hinge.step" in page.hrefs
    assert "points/c0.000_F200/loop.png" in page.hrefs


def test_unknown_folder_one_line_error(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("hello")
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "r.html")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert str(tmp_path) in err
    for expected in ("expected one of", "result.json", "trace.sqlite", "comparison.json"):
        assert expected in err
    assert not (tmp_path / "r.html").exists()
    assert main(["report", str(tmp_path / "absent"), "--out", str(tmp_path / "r.html")]) == 1
    assert "no such folder" in capsys.readouterr().err


def test_malformed_result_json_names_the_file(tmp_path, capsys):
    folder = _cycle_folder(tmp_path)
    (folder / "result.json").write_text("{not json")
    assert main(["report", str(folder)]) == 1
    err = capsys.readouterr().err
    assert str(folder / "result.json") in err
    assert len(err.strip().splitlines()) == 1


def test_chromium_check_catches_a_broken_image(chromium, tmp_path):
    """Control: the rendering check would see a broken image and report it on the console."""
    page = tmp_path / "broken.html"
    page.write_text(
        '<!DOCTYPE html><html><body><img alt="x" src="data:image/png;base64,iVBORw0KGgo=">'
        + CHECK_SCRIPT
        + "</body></html>"
    )
    r = _run_chromium(chromium, tmp_path, page, "--virtual-time-budget=10000", "--dump-dom")
    assert 'data-broken="[&quot;x&quot;]"' in r.stdout
    assert any("broken images: x" in line for line in _console_lines(r.stderr))


def test_cycle_report_renders_in_chromium(chromium, tmp_path):
    folder = _cycle_folder(tmp_path)
    out = folder / "report.html"
    assert main(["report", str(folder), "--out", str(out)]) == 0
    render_and_check(chromium, out, tmp_path)


def test_report_of_a_real_coarse_cycle(chromium, tmp_path):
    """``hingelab cycle`` on the coarse mesh, then its report, checked and rendered."""
    folder = tmp_path / "cycle"
    args = ["cycle", "--size", "4", "--contact-size", "2", "--increments", "6"]
    assert main([*args, "--no-progress", "--out", str(folder)]) == 0
    out = folder / "report.html"
    assert main(["report", str(folder), "--out", str(out)]) == 0
    page = check_structure(out)
    eta = json.loads((folder / "result.json").read_text())["eta"]
    assert f"{eta:.4g}" in " ".join(page.text)
    assert {"hinge.step", "mesh.vtu", "loop.csv", "fields/cycle.pvd"} <= set(page.hrefs)
    # the loop picture follows the "what was run" table and the headline numbers
    render_and_check(chromium, out, tmp_path, region=(950, 1350, 120, 780))


def _row(html_text: str, name: str) -> str:
    """The value of the row ``name`` of the page's "What was run" table, as text."""
    import html
    import re

    m = re.search(rf"<tr><th>{re.escape(name)}</th><td[^>]*>(.*?)</td></tr>", html_text, re.S)
    assert m, f"no row {name!r}"
    return html.unescape(re.sub(r"<[^>]+>", "", m.group(1)))


REPEATABILITY = Path(__file__).parents[3] / "validation" / "data" / "repeatability_example.csv"


def test_report_of_a_repeatability_folder(tmp_path, capsys):
    """The README's repeatability command makes a folder the report renders (it refused it)."""
    out = tmp_path / "rep"
    argv = ["repeatability", str(REPEATABILITY), "--length-mm", "25", "--out", str(out)]
    argv += ["--eta", "general=0.0659,modified=0.0160"]
    assert main(argv) == 0
    assert main(["report", str(out)]) == 0
    page = check_structure(out / "report.html")
    doc = json.loads((out / "repeatability.json").read_text())
    text = " ".join(page.text)
    assert "Repeatability" in text
    for h in doc["hinges"]:  # θ and σ of each hinge, as the analysis wrote them
        assert f"{h['theta_rad']:.4g}" in text
        assert f"{h['sigma_um']:.4g}" in text
    assert len(page.imgs) == 3  # two histograms and η–θ
    html_text = (out / "report.html").read_text(encoding="utf-8")
    assert _row(html_text, "command") == shlex.join(["hingelab", *argv])


def test_the_command_row_is_the_command_line_that_ran(jenkins, tmp_path, capsys):
    model = tmp_path / "MODEL.toml"
    model.write_text('[hinge]\nkind = "jenkins_pin"\n[cycle]\nincrements_per_stage = 8\n')
    out = tmp_path / "my cycle"  # a space: the row must quote it as a shell would
    argv = ["cycle", "--model", str(model), "--amplitude", "300", "--out", str(out)]
    assert main(argv) == 0
    refused = tmp_path / "refused"
    refused.mkdir()
    assert main([*argv[:-1], str(refused), "--mu", "-1"]) == 1
    assert list(refused.iterdir()) == []  # a command refused before any work records nothing
    assert main(["report", str(out)]) == 0
    html_text = (out / "report.html").read_text(encoding="utf-8")
    assert _row(html_text, "command") == shlex.join(["hingelab", *argv])
    assert "'" + str(out) + "'" in _row(html_text, "command")
    assert _row(html_text, "run in") == os.getcwd()
    assert "exit status 0" in _row(html_text, "ended")


def test_compare_report_shows_what_compare_judged_for_a_clearance_case(tmp_path):
    """A clearance case shows η without the free play (η′) and 'n/m' for the metrics compare
    could not measure, not the raw η with the free play or a dash (issue 33, item 4)."""
    data = _compare_json(("c300",))
    case = data["cases"][0]
    case.update(
        clearance_mm=0.1,
        free_play_removed=True,
        not_measurable=["W_cycle_Nmm", "eta"],
        errors={"disp_at_peak_mm": 0.001},
        measured={"eta": 1.4e-5, "eta_without_free_play": 0.000921},
        model={"eta": 1.5e-5, "eta_without_free_play": 0.00161},
    )
    d = tmp_path / "compare"
    _png(d / "error_map.png")
    (d / "comparison.json").write_text(json.dumps(data))
    assert main(["report", str(d)]) == 0
    text = " ".join(check_structure(d / "report.html").text)
    assert "0.000921 ′" in text
    assert "0.00161 ′" in text
    assert "1.4e-05" not in text
    assert text.count("n/m") >= 2  # the W and η cells (and the note)
