import numpy as np
import pytest

from rsm.metrics import fit_metrics
from rsm.paper import fit_paper_table
from rsm.paper_printed import GENERAL
from rsm.plots import axis_label, plot_all, plot_contour
from rsm.polynomial import fit_response_surface


def test_one_variable_surface_gets_slices_only(tmp_path):
    # The two-variable plots are written (and checked) by tests/studies/cli/test_rsm.py.
    x = np.linspace(0, 1, 6)[:, None]
    s = fit_response_surface(x, x[:, 0] ** 2, 2, x_names=("load_N",))
    out = plot_all(s, fit_metrics(s, warn=False), tmp_path)
    assert set(out) == {"slices", "predicted_vs_actual"}
    for p in out.values():
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("name", "label"),
    [
        ("clearance_mm", "clearance [mm]"),
        ("preload_N", "preload [N]"),
        ("eta", "loss factor η [–]"),
        ("ratio", "ratio"),
    ],
)
def test_axis_label(name, label):
    assert axis_label(name) == label


def test_contour_with_threshold_region(tmp_path):
    s = fit_paper_table(GENERAL)
    p = plot_contour(s, tmp_path / "contour.png", threshold=0.05)
    assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert p.stat().st_size > 10_000
