"""A user's own effects: from a file named in MODEL.toml, or from a package by entry point.

The hinge is the plug-in kind ``jenkins_pin`` (``tests/plugins``: no mesh, exact loops), so
every check is against a closed form and costs milliseconds. The user's file is the
documented example ``studies/examples/effects/damper.py`` (docs/user_effects.md), copied
next to a model file in a temporary folder.
"""

from __future__ import annotations

import math
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cad.errors import ParameterError
from fe.effects.registry import REGISTRY, effect_names, validate_effects
from model.file import read_model, write_model
from model.service import ModelService
from model.spec import DesignPoint, ModelSpec, result_key
from model.store import ResultStore

EXAMPLE = Path(__file__).parents[3] / "studies" / "examples" / "effects" / "damper.py"
RATE = 20.0  # [N/s]
FG = 400.0

MODEL = """[hinge]
kind = "jenkins_pin"
slip_force_n = 60.0

[cycle]
increments_per_stage = 40
grading = 1.0
force_rate_n_per_s = {rate}

[effects.damper]
from = "effects/damper.py:Damper"
{params}"""


def model_dir(tmp_path: Path, params: str, rate: float = RATE, name: str = "MODEL.toml") -> Path:
    """A model file with the example damper next to it (in ``effects/``)."""
    (tmp_path / "effects").mkdir(exist_ok=True)
    shutil.copy(EXAMPLE, tmp_path / "effects" / "damper.py")
    path = tmp_path / name
    path.write_text(MODEL.format(rate=rate, params=params))
    return path


def dashpot(fluidity: float) -> str:
    return f"fluidity_mm_per_ns = {fluidity!r}\nstiffness_n_per_mm = 0.0\n"


def run(spec: ModelSpec, service: ModelService | None = None) -> dict[str, float]:
    service = service or ModelService()
    return service.run_point(spec, DesignPoint(FG, {"slip_force_n": 60.0})).metrics()


def test_a_dashpot_in_a_users_file_runs_through_the_service_with_its_closed_form_work(
    jenkins, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    """MODEL.toml → service → cycle → metrics: the loop area is Jenkins' plus the dashpot's.

    A dashpot of fluidity φ under a force ramped at r between ±Fg dissipates, per loop,
    ``φ ∮F² dt = 4 φ Fg³ / (3 r)``; the element's own closed form is ``loop_area``.
    The trapezoid on 40 increments per stage is within 0.1 % of the integral.
    """
    from hingelab_jenkins import JenkinsParams, loop_area

    phi = 2e-6
    spec = read_model(model_dir(tmp_path, dashpot(phi)))
    assert "damper" in REGISTRY
    assert spec.effects["damper"]["fluidity_mm_per_ns"] == phi
    m = run(spec)
    viscous = 4.0 * phi * FG**3 / (3.0 * RATE)
    assert m["effect_work_Nmm"] == pytest.approx(viscous, rel=1e-3)
    w_jenkins = loop_area(JenkinsParams(), FG)
    assert m["W_cycle_Nmm"] == pytest.approx(w_jenkins + viscous, rel=1e-3)
    assert m["friction_work_Nmm"] == pytest.approx(w_jenkins, rel=1e-9)
    assert m["energy_balance_rel_err"] < 1e-12
    assert abs(m["elastic_energy_change_Nmm"]) < 1e-9 * m["W_cycle_Nmm"]  # a dashpot stores 0


def test_the_work_of_a_viscous_element_falls_with_the_loading_rate(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Rate dependence: the same dashpot loaded twice as fast dissipates half as much."""
    slow = run(read_model(model_dir(tmp_path, dashpot(2e-6), rate=10.0)))["effect_work_Nmm"]
    fast = run(read_model(model_dir(tmp_path, dashpot(2e-6), rate=20.0)))["effect_work_Nmm"]
    assert slow / fast == pytest.approx(2.0, rel=1e-9)


def test_a_kelvin_voigt_element_dissipates_what_an_independent_integration_gives(
    jenkins, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    """Spring ∥ dashpot in series: loop area = friction work + ∫ c ḣ² dt + Δ(½ k h²).

    The dashpot's dissipation and the spring's energy are integrated independently
    (scipy's ODE solver on the protocol's triangle wave, over the last loop; the element
    starts from rest, so its spring holds more at the loop's end than at its start).
    """
    from hingelab_jenkins import JenkinsParams, loop_area
    from scipy.integrate import solve_ivp

    phi, k = 5e-6, 1e4
    spec = read_model(
        model_dir(tmp_path, f"fluidity_mm_per_ns = {phi!r}\nstiffness_n_per_mm = {k!r}\n")
    )
    m = run(spec)
    ramp = 2 * FG / RATE  # one stage [s]
    t0 = FG / RATE  # the first stage 0 → +Fg

    def force(t: float) -> float:
        if t <= t0:
            return RATE * t
        u = (t - t0) % (2 * ramp)
        return FG - RATE * u if u <= ramp else -FG + RATE * (u - ramp)

    def rhs(t: float, y: list[float]) -> list[float]:
        h, _ = y
        hdot = phi * (force(t) - k * h)
        return [hdot, hdot**2 / phi]  # c ḣ² with c = 1/φ

    sol = solve_ivp(rhs, (0.0, t0 + 2 * ramp), [0.0, 0.0], rtol=1e-10, atol=1e-14,
                    max_step=0.05, dense_output=True)  # fmt: skip
    (h0, w0), (h1, w1) = sol.sol(t0), sol.sol(t0 + 2 * ramp)
    lost, stored = w1 - w0, 0.5 * k * (h1**2 - h0**2)
    assert m["effect_work_Nmm"] == pytest.approx(lost, rel=2e-3)
    assert m["elastic_energy_change_Nmm"] == pytest.approx(stored, rel=2e-3)  # Jenkins' is 0
    w = loop_area(JenkinsParams(), FG) + lost + stored
    assert m["W_cycle_Nmm"] == pytest.approx(w, rel=2e-3)
    assert m["energy_balance_rel_err"] < 1e-12


def test_the_from_key_survives_write_and_read_anywhere(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """``read_model(write_model(spec))`` is the spec, written beside the file or elsewhere."""
    spec = read_model(model_dir(tmp_path, dashpot(1e-6)))
    again = read_model(write_model(spec, tmp_path / "again.toml"))
    assert again == spec
    elsewhere = write_model(spec, tmp_path / "out" / "deep" / "MODEL.toml")
    assert 'from = "../../effects/damper.py:Damper"' in elsewhere.read_text()
    assert read_model(elsewhere) == spec


def test_an_effect_with_from_and_no_parameters_is_declared_not_switched_on(
    jenkins, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    spec = read_model(model_dir(tmp_path, ""))
    assert "damper" not in spec.effects
    assert "damper" in spec.effect_sources
    assert "damper" in effect_names()
    assert validate_effects({"damper": {}})["damper"]["stiffness_n_per_mm"] == 1e4  # defaults
    back = read_model(write_model(spec, tmp_path / "again.toml"))
    assert back == spec
    assert "damper" not in back.effects


def test_editing_the_file_gives_another_key_and_never_a_stale_result(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The key holds the file's hash: an edited effect is recomputed, not read from the store."""
    path = model_dir(tmp_path, dashpot(2e-6))
    store = ResultStore(tmp_path / "store")
    point = DesignPoint(FG, {"slip_force_n": 60.0})
    old = read_model(path)
    w_old = ModelService(store=store).run_point(old, point).metrics()["W_cycle_Nmm"]
    source = tmp_path / "effects" / "damper.py"
    source.write_text(
        source.read_text().replace(
            "return PostResult(history.disp_mm + h,", "return PostResult(history.disp_mm + 2 * h,"
        )
    )
    new = read_model(path)
    assert result_key(new, point) != result_key(old, point)
    service = ModelService(store=store)
    w_new = service.run_point(new, point).metrics()["W_cycle_Nmm"]
    assert service.n_computed == 1  # not read back from the store
    from hingelab_jenkins import JenkinsParams, loop_area

    w_j = loop_area(JenkinsParams(), FG)
    assert w_new - w_j == pytest.approx(2 * (w_old - w_j), rel=1e-9)  # h doubled
    # the spec read before the edit still runs the code its key names (kept by hash)
    assert ModelService().run_point(old, point).metrics()["W_cycle_Nmm"] == w_old


def test_an_unpickled_spec_registers_its_file_where_nothing_knew_it(
    jenkins, tmp_path, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    """A worker's view, in this process: the registry and the loaded files forgotten."""
    from fe.effects import plugins, registry

    spec = read_model(model_dir(tmp_path, dashpot(2e-6)))
    w = run(spec)["W_cycle_Nmm"]
    blob = pickle.dumps(spec)
    registry.unregister_effect("damper")
    monkeypatch.setattr(plugins, "_LOADED", {})
    assert "damper" not in REGISTRY
    back = pickle.loads(blob)
    assert back == spec
    assert "damper" in REGISTRY
    assert run(back)["W_cycle_Nmm"] == w


@pytest.mark.slow
def test_a_worker_process_loads_the_file_from_the_spec_it_receives(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A pickled spec carries its file's path and hash; a fresh interpreter runs it the same."""
    from tests.conftest import PLUGINS

    spec = read_model(model_dir(tmp_path, dashpot(2e-6)))
    blob = tmp_path / "spec.pickle"
    blob.write_bytes(pickle.dumps(spec))
    code = (
        "import pickle, sys\n"
        "from model.service import ModelService\n"
        "from model.spec import DesignPoint\n"
        "spec = pickle.loads(open(sys.argv[1], 'rb').read())\n"
        "r = ModelService().run_point(spec, DesignPoint(400.0, {'slip_force_n': 60.0}))\n"
        "print(repr(r.metrics()['W_cycle_Nmm']))\n"
    )
    env = {"PYTHONPATH": f"{PLUGINS}:{Path.cwd()}", "PATH": "/usr/bin:/bin"}
    out = subprocess.run(
        [sys.executable, "-c", code, str(blob)],
        capture_output=True, text=True, env=env, cwd=Path.cwd(), check=False, timeout=120,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert float(out.stdout.strip()) == run(spec)["W_cycle_Nmm"]


def test_an_effect_from_an_installed_package_is_found_by_its_entry_point(
    jenkins, grips, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    """``grip_compliance`` (tests/plugins/effects): δ(±Fg) move by ±c Fg, the area stays."""
    from fe.effects.plugins import file_hash
    from model.spec import effect_code
    from tests.conftest import EFFECT_PLUGINS

    assert grips in effect_names()
    path = tmp_path / "MODEL.toml"
    path.write_text(
        '[hinge]\nkind = "jenkins_pin"\n\n[effects.grip_compliance]\ngrip_mm_per_n = 1e-4\n'
    )
    spec = read_model(path)
    base = run(dataclass_replace(spec, effects={}))
    m = run(spec)
    assert m["disp_at_peak_mm"] - base["disp_at_peak_mm"] == pytest.approx(1e-4 * FG, rel=1e-9)
    assert m["W_cycle_Nmm"] == pytest.approx(base["W_cycle_Nmm"], rel=1e-9)
    assert effect_code(spec) == {
        grips: file_hash(EFFECT_PLUGINS / "hingelab_grips" / "__init__.py")
    }


def dataclass_replace(spec: ModelSpec, **changes: object) -> ModelSpec:
    import dataclasses

    return dataclasses.replace(spec, **changes)


def test_a_users_effect_cannot_take_a_built_in_name(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = model_dir(tmp_path, "")
    path.write_text(path.read_text().replace("[effects.damper]", "[effects.frame_compliance]"))
    with pytest.raises(ParameterError, match=r"\[effects.frame_compliance\].*built-in effect"):
        read_model(path)


def test_the_protocol_time_is_the_force_path_at_the_stated_rate() -> None:
    import numpy as np

    from fe.effects.history import protocol_time

    F = np.array([0.0, 100.0, 400.0, 400.0, -400.0])
    assert protocol_time(F, 20.0).tolist() == [0.0, 5.0, 20.0, 20.0, 60.0]
    assert math.isclose(protocol_time(F, 40.0)[-1], 30.0)


def test_the_docs_show_the_example_files_as_they_are() -> None:
    """docs/user_effects.md holds the whole example and its test, verbatim."""
    doc = (EXAMPLE.parents[3] / "docs" / "user_effects.md").read_text()
    assert EXAMPLE.read_text() in doc
    assert (EXAMPLE.parent / "test_damper.py").read_text() in doc
