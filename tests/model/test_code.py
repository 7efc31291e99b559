"""Results are keyed by the code that computed them, and workers must run this process's code."""

from __future__ import annotations

import dataclasses
import logging
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import model.code as code
import model.spec as spec_module
from cad.errors import DataError, ParameterError
from cad.provenance import CYCLE_LIBRARIES, source_digest
from model.cluster import _Drive, dispatch, other_code, worker_code
from model.code import ALL_PACKAGES, CYCLE_PACKAGES, CodeVersion, code_version, plugin_digest
from model.dispatch import Dispatcher
from model.file import read_model
from model.service import ModelService
from model.spec import DesignPoint, content_hash, kind_code, result_key
from model.store import ResultStore


def _package(root: Path, name: str) -> Path:
    pkg = root / name
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text('"""A package."""\n')
    (pkg / "a.py").write_text("X = 1\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "b.py").write_text("Y = 2\n")
    return pkg


def _digest(name: str) -> str:
    source_digest.cache_clear()
    return source_digest((name,))


def test_the_source_digest_follows_every_python_file_and_only_them(tmp_path, monkeypatch):
    pkg = _package(tmp_path, "probe_pkg_digest")
    monkeypatch.syspath_prepend(str(tmp_path))
    first = _digest("probe_pkg_digest")
    assert len(first) == 64
    (pkg / "a.py").write_text("X = 2\n")  # one character of one file
    edited = _digest("probe_pkg_digest")
    assert edited != first
    (pkg / "a.py").write_text("X = 1\n")
    assert _digest("probe_pkg_digest") == first  # the content, not the file's time
    (pkg / "sub" / "table.csv").write_text("a,b\n")  # not code
    assert _digest("probe_pkg_digest") == first
    (pkg / "sub" / "c.py").write_text("")  # a new, empty module is code
    assert _digest("probe_pkg_digest") != first
    (pkg / "sub" / "c.py").rename(pkg / "sub" / "d.py")  # so is its name
    renamed = _digest("probe_pkg_digest")
    assert renamed not in (first, edited)
    with pytest.raises(ParameterError, match="'no_such_package_here' is not an importable package"):
        _digest("no_such_package_here")


def test_code_version_holds_the_version_the_source_and_the_cycle_libraries():
    v = code_version()
    assert v.version == code.package_version()
    assert v.source == source_digest(CYCLE_PACKAGES)
    assert dict(v.libraries).keys() == set(CYCLE_LIBRARIES)
    assert v.short() == f"{v.version}+src.{v.source[:12]}"
    # the whole distribution is another digest than the packages that compute a cycle
    assert code_version(ALL_PACKAGES).source != v.source
    other = dataclasses.replace(v, libraries=(*v.libraries[:-1], (v.libraries[-1][0], "0.0")))
    assert content_hash(other) != content_hash(v)  # the name of a code's cache folder
    assert v.differences(v) == []
    assert v.differences(other) == [f"{v.libraries[-1][0]} {v.libraries[-1][1]} against 0.0"]


def _jenkins_spec(tmp_path: Path) -> Any:
    path = tmp_path / "MODEL.toml"
    path.write_text(
        '[hinge]\nkind = "jenkins_pin"\nk0_n_per_mm = 2000.0\nk1_n_per_mm = 6000.0\n'
        "slip_force_n = 60.0\n"
    )
    return read_model(path)


def test_a_result_stored_by_other_code_is_computed_again(jenkins, tmp_path, monkeypatch):
    spec, point = _jenkins_spec(tmp_path), DesignPoint(150.0)
    store = ResultStore(tmp_path / "results")
    first = ModelService(store=store)
    first.run(spec, [point])
    again = ModelService(store=store)
    again.run(spec, [point])
    assert (first.n_computed, again.n_computed, again.n_cached) == (1, 0, 1)
    here = code_version()
    edited = dataclasses.replace(here, source="0" * 64)  # as after an edit of fe/
    monkeypatch.setattr(spec_module, "code_version", lambda: edited)
    later = ModelService(store=store)
    later.run(spec, [point])
    assert (later.n_computed, later.n_cached) == (1, 0)


def test_a_plug_in_kind_is_keyed_by_its_own_package(jenkins, tmp_path, monkeypatch):
    spec, point = _jenkins_spec(tmp_path), DesignPoint(150.0)
    assert kind_code(spec) == plugin_digest("hingelab_jenkins") != ""
    general = read_model(Path(__file__).parents[2] / "studies/examples/MODEL.toml")
    assert kind_code(general) == ""  # hingelab's own kinds: keyed with its source
    key = result_key(spec, point)
    monkeypatch.setattr(spec_module, "plugin_digest", lambda module: "1" * 64)
    assert result_key(spec, point) != key


def test_a_plug_in_modules_digest_is_its_packages_or_its_files(tmp_path, monkeypatch):
    _package(tmp_path, "probe_pkg_plugin")
    (tmp_path / "probe_single_module.py").write_text("K = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    plugin_digest.cache_clear()
    source_digest.cache_clear()
    assert plugin_digest("probe_pkg_plugin.sub.b") == source_digest(("probe_pkg_plugin",))
    single = plugin_digest("probe_single_module")
    (tmp_path / "probe_single_module.py").write_text("K = 2\n")
    plugin_digest.cache_clear()
    assert plugin_digest("probe_single_module") != single
    with pytest.raises(ParameterError, match="probe_nowhere"):
        plugin_digest("probe_nowhere")


class _Client:
    """Stands in for a ``dask.distributed.Client``: workers and the code each reports."""

    def __init__(self, codes: dict[str, CodeVersion]) -> None:
        self.codes = codes
        self.asked: list[list[str]] = []

    def scheduler_info(self) -> dict[str, Any]:
        return {"workers": {w: {"nthreads": 1} for w in self.codes}}

    def run(self, fn: Any, workers: list[str]) -> dict[str, CodeVersion]:
        assert fn is worker_code
        self.asked.append(workers)
        return {w: self.codes[w] for w in workers}

    def submit(self, *args: Any, **kwargs: Any) -> Any:
        raise AssertionError("no job may be submitted to a cluster that runs other code")


def test_dispatch_refuses_a_cluster_whose_worker_runs_other_code(jenkins, tmp_path):
    here = worker_code()
    assert here == code_version(ALL_PACKAGES)
    other = dataclasses.replace(here, source="f" * 64)
    client = _Client({"tcp://a:1": here, "tcp://b:2": other})
    assert other_code(client, ["tcp://a:1"]) == {}
    jobs = [(_jenkins_spec(tmp_path), DesignPoint(150.0))]
    with pytest.raises(DataError, match=r"Dask worker tcp://b:2 runs other code .*source") as err:
        dispatch(client, jobs, lambda *a: None, lambda *a: None)
    assert f"source {here.source[:12]} against ffffffffffff" in str(err.value)
    assert client.asked[-1] == ["tcp://a:1", "tcp://b:2"]  # every worker, before any job


def test_a_worker_that_joins_with_other_code_is_not_used(jenkins, tmp_path, caplog):
    here = worker_code()
    client = _Client({"tcp://a:1": here})
    plan = Dispatcher(["g"])
    plan.add_worker("tcp://a:1", 1)
    drive = _Drive(client, plan, [(None, None)], lambda *a: None, lambda *a: None, lambda j: ())
    client.codes["tcp://late:3"] = dataclasses.replace(here, version="9.9")
    client.codes["tcp://good:4"] = here
    with caplog.at_level(logging.WARNING, logger="model.cluster"):
        drive._follow_workers()
        drive._follow_workers()  # asked once, not at every poll
    assert plan.workers == ["tcp://a:1", "tcp://good:4"]
    assert client.asked == [["tcp://good:4", "tcp://late:3"]]
    assert "tcp://late:3 joined running other code (hingelab" in caplog.text

    def no_hingelab(fn: Any, workers: list[str]) -> Any:
        raise ModuleNotFoundError("No module named 'model'")

    client.codes["tcp://bare:5"] = here
    client.run = no_hingelab  # type: ignore[method-assign]
    drive._follow_workers()  # the run goes on without it
    assert plan.workers == ["tcp://a:1", "tcp://good:4"]
    assert "tcp://bare:5 joined running other code (the Dask workers cannot report" in caplog.text


def test_version_prints_the_source_digest():
    out = subprocess.run(
        [sys.executable, "-m", "studies.cli.main", "--version"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == f"hingelab {code_version(ALL_PACKAGES).short()}"


def test_the_lu_threads_key_a_result_as_they_change_its_last_bits(jenkins, tmp_path, monkeypatch):
    spec, point = _jenkins_spec(tmp_path), DesignPoint(150.0)
    monkeypatch.delenv("HINGELAB_LU_THREADS", raising=False)
    key = result_key(spec, point)
    monkeypatch.setenv("HINGELAB_LU_THREADS", "2")
    assert result_key(spec, point) != key
    monkeypatch.setenv("HINGELAB_LU_THREADS", "1")  # the default, spelt out
    assert result_key(spec, point) == key
