"""Bluehill exports from decimal-comma locales and with ``(sec)`` read as the plain export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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
    lines[-1] = lines[-1].replace(
        '"30.50000"', '"1,000.10000"'
    )  # the last sample: time still rises
    path.write_text("\n".join(lines) + "\n")
    assert read_bluehill(path).time_s[-1] == 1000.1


def _plain_loop(sep: str = ",", decimal: str = ".") -> str:
    rows = [("time_s", "force_N", "displacement_mm")]
    force = [0.0, 150.5, 300.0, 0.0, -300.0, 0.0, 300.0]
    for k, f in enumerate(force):
        rows.append((f"{0.5 * k}", f"{f}", f"{f / 1e4 + 0.0012}"))
    text = "\n".join(sep.join(r) for r in rows) + "\n"
    return text.replace(".", decimal) if decimal != "." else text


@pytest.mark.parametrize(
    ("sep", "decimal"),
    [(";", ","), (";", "."), ("\t", ","), ("\t", ".")],
    ids=["semicolon-comma", "semicolon-point", "tab-comma", "tab-point"],
)
def test_plain_csv_as_spreadsheets_write_it(tmp_path, sep, decimal):
    """A plain loop CSV separated by ';' or tabs, with decimal commas or points, reads the
    same numbers as the comma-separated file (issue 33: it was refused)."""
    from validation.loop_files import read_loop_csv

    ref = tmp_path / "ref.csv"
    ref.write_text(_plain_loop())
    other = tmp_path / "other.csv"
    other.write_text(
        _plain_loop(sep, decimal).replace("force_N", "force_N").replace("time_s", "time_s")
    )
    a, b = read_loop_csv(ref), read_loop_csv(other)
    np.testing.assert_array_equal(a.force_n, b.force_n)
    np.testing.assert_array_equal(a.displacement_mm, b.displacement_mm)
    np.testing.assert_array_equal(a.time_s, b.time_s)


def test_decimal_commas_in_a_comma_separated_file_say_the_fix(tmp_path):
    from cad.errors import DataError
    from validation.loop_files import read_loop_csv

    path = tmp_path / "loop.csv"
    path.write_text(_plain_loop(",", ","))
    with pytest.raises(DataError, match="separate the columns with ';'"):
        read_loop_csv(path)


def test_time_going_backwards_is_refused_naming_the_line(tmp_path):
    from cad.errors import DataError
    from validation.loop_files import read_loop_csv

    path = tmp_path / "loop.csv"
    text = _plain_loop().splitlines()
    text[4] = text[4].replace("1.5,", "0.2,", 1)  # line 5: time 1.5 s written as 0.2 s
    path.write_text("\n".join(text) + "\n")
    with pytest.raises(
        DataError, match=r"line 5, column time_s: time does not increase \(1 s, then 0.2 s\)"
    ):
        read_loop_csv(path)
