"""Bluehill exports from decimal-comma locales and with ``(sec)`` read as the plain export."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from validation.loop_files import read_bluehill, read_loop_file

BLUEHILL = Path(__file__).parent / "data" / "bluehill_hinge_300N.csv"


def test_sec_unit_reads_as_seconds(tmp_path):
    path = tmp_path / "sec.csv"
    path.write_text(BLUEHILL.read_text().replace('"(s)"', '"(sec)"', 1))
    a, b = read_bluehill(BLUEHILL), read_bluehill(path)
    assert a.time_s is not None
    assert b.time_s is not None
    np.testing.assert_array_equal(a.time_s, b.time_s)


def test_semicolon_export_with_decimal_commas(tmp_path):
    text = BLUEHILL.read_text().replace('","', '";"')
    body = [
        line if not line[1:2].isdigit() else line.replace(".", ",") for line in text.splitlines()
    ]
    path = tmp_path / "de.csv"
    path.write_text("\n".join(body) + "\n")
    assert '"0,002125"' in path.read_text()
    a, b = read_bluehill(BLUEHILL), read_loop_file(path)
    np.testing.assert_array_equal(a.force_n, b.force_n)
    np.testing.assert_array_equal(a.displacement_mm, b.displacement_mm)


def test_decimal_comma_in_a_comma_separated_export(tmp_path):
    """``"0,002125"`` is a decimal comma (was read as 2125 mm); ``"1,234.5"`` stays thousands."""
    lines = BLUEHILL.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith('"0.10000"'))
    lines[k] = lines[k].replace('"0.002103"', '"0,002103"')
    path = tmp_path / "mixed.csv"
    path.write_text("\n".join(lines) + "\n")
    a, b = read_bluehill(BLUEHILL), read_bluehill(path)
    np.testing.assert_array_equal(a.displacement_mm, b.displacement_mm)
    lines[k] = lines[k].replace('"0.10000"', '"1,000.10000"')
    path.write_text("\n".join(lines) + "\n")
    assert read_bluehill(path).time_s[1] == 1000.1
