import numpy as np
import pytest

from cad.errors import DataError
from rsm.tables import read_table, read_xy


def _write(tmp_path, text, name="t.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_reads_and_labels_rows(tmp_path):
    p = _write(tmp_path, "a_mm,b_N,eta\n0,1,0.5\n1,2,0.7\n2,1,0.9\n")
    xy = read_xy(p, ["a_mm", "b_N"], "eta")
    np.testing.assert_array_equal(xy.x, [[0, 1], [1, 2], [2, 1]])
    assert xy.labels == ("row 1", "row 2", "row 3")


def test_point_id_column_gives_point_labels(tmp_path):
    p = _write(tmp_path, "point_id,a,y\n7,0,1\n9,1,2\n")
    assert read_xy(p, ["a"], "y").labels == ("point 7", "point 9")


def test_missing_column_named_with_those_present(tmp_path):
    p = _write(tmp_path, "a,y\n0,1\n1,2\n")
    with pytest.raises(DataError, match=r"no column 'b'; columns are a, y"):
        read_xy(p, ["a", "b"], "y")


@pytest.mark.parametrize("bad", ["nan", "", "abc", "inf"], ids=["nan", "blank", "text", "inf"])
def test_non_number_named_by_line_and_column(tmp_path, bad):
    p = _write(tmp_path, f"a,y\n0,1\n1,{bad}\n")
    with pytest.raises(DataError, match=r"t.csv: line 3, column 'y'"):
        read_xy(p, ["a"], "y")


def test_constant_column_rejected(tmp_path):
    p = _write(tmp_path, "a,b,y\n0,5,1\n1,5,2\n2,5,3\n")
    with pytest.raises(DataError, match="column 'b' is constant"):
        read_xy(p, ["a", "b"], "y")


def test_ragged_row_and_duplicate_header(tmp_path):
    with pytest.raises(DataError, match="line 3 has 3 cells"):
        read_table(_write(tmp_path, "a,y\n0,1\n1,2,3\n"))
    with pytest.raises(DataError, match="'a' appears twice"):
        read_table(_write(tmp_path, "a,a\n0,1\n", "d.csv"))


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_table("/nonexistent/table.csv")
