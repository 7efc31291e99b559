"""A rerun with nothing changed reuses the paper's surface figures; a change draws them again."""

from __future__ import annotations

from pathlib import Path

from studies.paper.study import current_figures


def test_figures_are_drawn_again_only_when_their_inputs_change(tmp_path: Path) -> None:
    calls = []

    def draw() -> dict[str, Path]:
        calls.append(1)
        path = tmp_path / "figures" / "g_contour.png"
        path.parent.mkdir(exist_ok=True)
        path.write_bytes(b"png")
        return {"contour": path}

    stamp = tmp_path / "figures" / ".g.json"
    first = current_figures(stamp, {"table": "a,b\n1,2\n"}, draw)
    again = current_figures(stamp, {"table": "a,b\n1,2\n"}, draw)
    assert again == first
    assert len(calls) == 1  # nothing changed: not redrawn
    current_figures(stamp, {"table": "a,b\n1,3\n"}, draw)
    assert len(calls) == 2  # another table: redrawn
    first["contour"].unlink()
    current_figures(stamp, {"table": "a,b\n1,3\n"}, draw)
    assert len(calls) == 3  # a figure missing: redrawn


def test_the_threshold_map_is_read_back_until_a_surface_changes(
    tmp_path: Path, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    from types import SimpleNamespace

    import numpy as np

    import studies.paper.checks as checks

    calls = []

    def compare(surfaces, out, figure):  # type: ignore[no-untyped-def]
        calls.append(1)
        (out / figure).parent.mkdir(parents=True, exist_ok=True)
        (out / figure).write_bytes(b"png")
        c0 = float(surfaces["general"].coefficients[0])
        return {"general": {"fraction_below": c0, "range": (0.1, float("nan"))}, "figure": figure}

    monkeypatch.setattr(checks, "threshold_comparison", compare)

    def surface(c0: float) -> SimpleNamespace:
        return SimpleNamespace(
            x_names=("clearance_mm", "amplitude_N"),
            coefficients=np.array([c0, 0.5]),
            center=np.array([0.2, 300.0]),
            half_range=np.array([0.2, 200.0]),
        )

    first = checks.current_threshold({"general": surface(0.25), "modified": None}, tmp_path)
    again = checks.current_threshold({"general": surface(0.25), "modified": None}, tmp_path)
    assert len(calls) == 1  # the same surfaces: read back
    assert (
        again
        == first
        == {
            "general": {"fraction_below": 0.25, "range": [0.1, None]},
            "figure": "figures/eta_0.05_both_hinges.png",
        }
    )
    changed = checks.current_threshold({"general": surface(0.26), "modified": None}, tmp_path)
    assert len(calls) == 2  # a coefficient changed: computed again
    assert changed["general"]["fraction_below"] == 0.26
    (tmp_path / changed["figure"]).unlink()
    checks.current_threshold({"general": surface(0.26), "modified": None}, tmp_path)
    assert len(calls) == 3  # the figure missing: drawn again
