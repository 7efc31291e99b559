"""Case ids are data, not paths: nothing a measurement folder says is written outside --out."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from model.paths import file_stem, inside
from studies.cli.main import main

MODEL = '[hinge]\nkind = "jenkins_pin"\n[cycle]\nincrements_per_stage = 12\n'

HOSTILE = ["../../evil", "/tmp/hingelab-abs", "a/b", "CON", "..", "nul.txt", "x" * 300]


@pytest.mark.parametrize("name", HOSTILE)
def test_a_file_stem_is_one_plain_name(name: str) -> None:
    stem = file_stem(name)
    assert stem
    assert "/" not in stem
    assert "\\" not in stem
    assert not stem.startswith(".")
    assert len(stem) <= 100
    assert stem.split(".")[0].lower() not in {"con", "nul"}


def test_different_names_give_different_stems() -> None:
    assert len({file_stem(n) for n in [*HOSTILE, "a_b", "a-b", "evil"]}) == len(HOSTILE) + 3
    assert file_stem("c300_bad") == "c300_bad"  # a safe id is kept as it is


def test_inside_refuses_a_path_that_leaves_the_folder(tmp_path: Path) -> None:
    from cad.errors import DataError

    assert inside(tmp_path, tmp_path / "loops" / "a.png") == tmp_path / "loops" / "a.png"
    with pytest.raises(DataError, match="outside the output folder"):
        inside(tmp_path, tmp_path / ".." / "evil.png")


def test_compare_writes_hostile_case_ids_inside_out(jenkins, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    data, model = tmp_path / "work" / "data", tmp_path / "work" / "MODEL.toml"
    model.parent.mkdir()
    model.write_text(MODEL)
    cases = ";".join(f"60:{a}" for a in (150, 200, 250, 300, 350, 400, 450))
    assert main(["synth", str(model), "--cases", cases, "--seed", "2", "--out", str(data)]) == 0
    with (data / "cases.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    for row, name in zip(rows, HOSTILE, strict=True):
        row["case_id"] = name
    with (data / "cases.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    before = {p for p in tmp_path.rglob("*")}
    out = tmp_path / "work" / "out"
    assert main(["compare", str(model), str(data), "--out", str(out)]) == 0
    new = {p for p in tmp_path.rglob("*")} - before
    assert new, "compare wrote nothing"
    outside = sorted(str(p) for p in new if out not in p.parents and p != out)
    assert not outside
    assert not Path("/tmp/hingelab-abs.png").exists()
    assert len(list((out / "loops").glob("*.png"))) == len(HOSTILE)  # one picture per case
