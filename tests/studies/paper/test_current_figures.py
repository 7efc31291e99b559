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
