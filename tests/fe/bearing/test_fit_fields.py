"""Field recovery of the bearing hinge with frictional fits (``FitSystem.displacement``).

The recovered field is checked against what the condensed solver reports, at converged
increments of a coarse cycle: the fits' contact rows against the state's relative
displacements ``w − w0`` (``w = W p + G α + w_free``, ``w0`` the exact initial gap in the
normal component), the ball rows against the ball coordinates ``v``, the grip against δ.
"""

from __future__ import annotations

import numpy as np
import pytest

from cad.bearing import make_bearing_hinge, without_balls
from cad.bearing_geometry import BearingHingeParams
from fe.bearing.fit_cycle import run_fit_cycle
from fe.bearing.fits import GRIP, FitSystem, build_fit_system, with_frictional_fits
from fe.bearing.report import fit_fields
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult
from fe.kinds import hinge_kind
from mesh.build import mesh_hinge

COARSE = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}

pytestmark = pytest.mark.slow  # a coarse build (~35 s) and a short cycle


@pytest.fixture(scope="module")
def cycle() -> tuple[FitSystem, CycleResult]:
    p = BearingHingeParams()
    model = with_frictional_fits(without_balls(make_bearing_hinge(p)))
    mesh, _ = mesh_hinge(model, hinge_kind("bearing").mesh_settings(**COARSE))
    system = build_fit_system(mesh, p)
    settings = CycleSettings(amplitude_n=400.0, increments_per_stage=4, mu=0.2)
    return system, run_fit_cycle(system, settings, 100.0)[0]


def test_recovered_field_reproduces_the_condensed_solution(
    cycle: tuple[FitSystem, CycleResult],
) -> None:
    system, result = cycle
    assert result.ball_coordinates is not None
    plus = int(np.argmax([i.force_n for i in result.increments]))  # first +Fg
    chosen = [0, plus, len(result.increments) - 1]
    coords = result.ball_coordinates[np.array(chosen) + 1].T  # row 0 is the preload
    p = np.column_stack([np.ravel(result.states[k].p) for k in chosen])
    alpha = np.column_stack([np.asarray(result.states[k].alpha) for k in chosen])
    u = system.displacement(p, coords[:-1], alpha, coords[-1])
    assert u.shape == (system.n_dof, len(chosen))
    u_ind = u[system.ties.independent]
    w0 = np.zeros((system.n_points, 3))
    w0[:, 0] = system.geo.g0
    grip = system.mesh.set_nodes("clevis_load")
    for j, k in enumerate(chosen):
        # (1) the contact rows: C u = w − w0 = W_c p − X r_b + G α
        w = np.ravel(np.asarray(result.states[k].w) - w0)
        assert np.abs(system.C @ u_ind[:, j] - w).max() <= 1e-8 * np.abs(w).max()
        # (2) the ball rows: Bt u = v, i.e. the balls are in equilibrium with the true law
        v = coords[:-1, j]
        assert np.abs(system.Bt @ u_ind[:, j] - v).max() <= 1e-8 * np.abs(v).max()
        # (3) the grip face moves by the loop's δ
        delta = result.increments[k].disp_mm
        assert delta == alpha[GRIP, j]
        np.testing.assert_allclose(u[3 * grip, j], delta, rtol=1e-12)
        np.testing.assert_allclose(u[3 * grip + 1, j], 0.0, atol=1e-15)
        np.testing.assert_allclose(u[3 * grip + 2, j], 0.0, atol=1e-15)
    # µm scale at 400 N; the pin is pushed along +x with the clevis at +Fg
    mag = np.linalg.norm(u[:, 1].reshape(-1, 3), axis=1)
    assert 1e-3 < mag.max() < 0.05
    pin = system.mesh.part_nodes("pin")
    assert u[3 * pin, 1].mean() > 0.0
    # the batch helper of the series gives the same fields
    fields = fit_fields(system, result, chosen)
    np.testing.assert_allclose(fields[1], u[:, 1].reshape(-1, 3), rtol=0, atol=1e-15)


def test_a_state_off_equilibrium_fails_the_self_check(
    cycle: tuple[FitSystem, CycleResult],
) -> None:
    """The ball rows are a real check: ball coordinates off the solution are not reproduced."""
    system, result = cycle
    assert result.ball_coordinates is not None
    k = len(result.increments) - 1
    c = result.ball_coordinates[k + 1]
    v = c[:-1] * 1.01  # 1 % off the converged balls
    u = system.displacement(
        np.ravel(result.states[k].p)[:, None],
        v[:, None],
        np.asarray(result.states[k].alpha)[:, None],
        np.array([c[-1]]),
    )
    off = np.abs(system.Bt @ u[system.ties.independent, 0] - v).max()
    assert off > 1e-4 * np.abs(v).max()
