"""What ``hingelab cycle`` tells and leaves behind when a cycle is not clean.

On the plug-in kind ``jenkins_pin`` (no mesh, an exact cycle in milliseconds), whose cycle
function is replaced to put in what is tested: a poor energy balance, recovered cut-backs,
a convergence failure with a partial loop, an interruption (during the cycle or while the
files are written).
"""

from __future__ import annotations

import dataclasses
import json

import pytest

from cad.errors import ConvergenceError
from model.code import code_version
from studies.cli.main import main

MODEL = '[hinge]\nkind = "jenkins_pin"\n\n[cycle]\nincrements_per_stage = 12\n'


@pytest.fixture
def cycle_cmd(jenkins, tmp_path):  # type: ignore[no-untyped-def]
    model = tmp_path / "MODEL.toml"
    model.write_text(MODEL)
    out = tmp_path / "out"
    return ["cycle", "--model", str(model), "--amplitude", "300", "--out", str(out)], out


def _replace_cycle(monkeypatch, change):  # type: ignore[no-untyped-def]
    import hingelab_jenkins

    real = hingelab_jenkins.run_jenkins_cycle
    monkeypatch.setattr(hingelab_jenkins, "run_jenkins_cycle", lambda p, s: change(real(p, s)))


def test_a_poor_energy_balance_is_a_warning_with_the_value_and_the_option(
    cycle_cmd, monkeypatch, capsys
):
    def lossy(r):  # friction work 4 % above the loop area
        incs = [dataclasses.replace(i, friction_work=1.04 * i.friction_work) for i in r.increments]
        return dataclasses.replace(r, increments=tuple(incs))

    _replace_cycle(monkeypatch, lossy)
    argv, out = cycle_cmd
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "hingelab cycle: warning: the energy balance closes only to 4 %" in err
    assert "raise --increments (MODEL.toml [cycle] increments_per_stage" in err
    summary = json.loads((out / "result.json").read_text())
    assert len(summary["warnings"]) == 1
    assert "4 %" in summary["warnings"][0]


def test_a_clean_cycle_has_no_warning_and_no_cutbacks(cycle_cmd, capsys):
    argv, out = cycle_cmd
    assert main(argv) == 0
    assert "warning" not in capsys.readouterr().err
    summary = json.loads((out / "result.json").read_text())
    assert (summary["warnings"], summary["cutbacks"]) == ([], 0)
    assert summary["code"] == code_version().short()  # which code computed it


def test_recovered_cutbacks_are_counted_in_the_result_and_the_printed_summary(
    cycle_cmd, monkeypatch, capsys
):
    _replace_cycle(monkeypatch, lambda r: dataclasses.replace(r, cutbacks=((3, 1), (7, 2))))
    argv, out = cycle_cmd
    assert main(argv) == 0
    printed = capsys.readouterr()
    assert "3 cut-backs" in printed.out
    assert "warning" not in printed.err  # 2 of 50 increments: not many
    assert json.loads((out / "result.json").read_text())["cutbacks"] == 3


def test_a_failed_cycle_keeps_its_partial_loop_under_its_own_name(cycle_cmd, monkeypatch, capsys):
    argv, out = cycle_cmd
    assert main(argv) == 0  # an earlier complete run in the same folder
    capsys.readouterr()

    def fail(r):
        partial = dataclasses.replace(r, increments=r.increments[:9])
        raise ConvergenceError("stuck", increment=9, iteration=60, residual=0.3, partial=partial)

    _replace_cycle(monkeypatch, fail)
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "increment 9, iteration 60, residual 3.000e-01" in err
    assert "the 9 converged increments are in" in err
    assert len((out / "loop_partial.csv").read_text().splitlines()) == 1 + 10  # header, 0, 9
    # nothing of the earlier run is left to pass for this one's
    assert not (out / "loop.csv").exists()
    assert not (out / "result.json").exists()


def test_an_interrupted_cycle_says_it_recomputes_and_leaves_no_loop(cycle_cmd, monkeypatch, capsys):
    def interrupt(r):
        raise KeyboardInterrupt

    _replace_cycle(monkeypatch, interrupt)
    argv, out = cycle_cmd
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "rerun the same command to recompute" in err
    assert "resume" not in err
    assert not (out / "loop.csv").exists()


def test_an_interruption_while_writing_leaves_no_loop_without_its_result(
    cycle_cmd, monkeypatch, capsys
):
    from fe.cycle import loop_files

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(loop_files, "write_loop_png", interrupt)
    argv, out = cycle_cmd
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "recompute" in err
    assert "resume" not in err
    assert not (out / "loop.csv").exists()
    assert not (out / "result.json").exists()
