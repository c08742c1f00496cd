"""Lagged friction (``Params.oc_friction = "lagged"``, docs/method/dda.md §4.3): sliding
contacts take the normal force of the last solve, K stays symmetric, and the open-close
iteration reaches the state the coupled (implicit, LU) iteration reaches, on a block sliding
down an incline with the closed form d = ½·g·(sinθ − cosθ·tanφ)·t²."""

import numpy as np
import pytest

import ddatai as dd
from cases import G, downslope_displacement, sliding_scene


def _run(theta, phi, friction, convergence):
    scene, block = sliding_scene(theta, phi)
    params = dd.Params(oc_friction=friction, **convergence)
    res = dd.simulate(scene, duration=1.0, params=params, record_contacts=True)
    _, states = res.contacts(-1)
    return downslope_displacement(res, block, theta), states


@pytest.mark.parametrize("convergence", [{}, dd.STRICT_CONVERGENCE], ids=["default", "strict"])
@pytest.mark.parametrize("theta, phi", [(30.0, 20.0), (45.0, 30.0)])
def test_lagged_friction_slides_as_the_coupled_iteration(theta, phi, convergence):
    """Both iterations accept the sliding state at both contacts and follow the closed form
    within 1e-3 (§7a). They differ by what the convergence test lets each contact's friction
    differ from N·tanφ: oc_force_tolerance × the block's weight at each of the two contacts
    (the default) or × its strength (strict), i.e. a downslope acceleration within 2·tol·g,
    a displacement within tol·g·t² after t = 1 s."""
    th, ph = np.radians(theta), np.radians(phi)
    exact = 0.5 * G * (np.sin(th) - np.cos(th) * np.tan(ph))
    d_lag, s_lag = _run(theta, phi, "lagged", convergence)
    d_cpl, s_cpl = _run(theta, phi, "coupled", convergence)
    for d, states in ((d_lag, s_lag), (d_cpl, s_cpl)):
        assert abs(d - exact) / exact < 1e-3, (d, exact)
        assert len(states) == 2 and np.all(states == dd.ContactState.SLIDE)
    tol = dd.Params(**convergence).oc_force_tolerance
    assert abs(d_lag - d_cpl) <= tol * G * 1.0 ** 2


def test_lagged_friction_solves_symmetric_systems_only():
    """A sliding block's steps under lagged friction factorise no non-symmetric K (the
    coupled iteration factorises an LU for every sliding step)."""
    from ddatai.step import Stepper

    counts = {}
    for friction in ("lagged", "coupled"):
        scene, _ = sliding_scene(30.0, 20.0)
        model = dd.build_model(scene, dd.Params(oc_friction=friction, solver="scipy"))
        stepper = Stepper(model)
        state = model.initial_state()
        for _ in range(20):
            state, _ = stepper.step(state)
        counts[friction] = stepper.solver.lu_factorisations
    assert counts["lagged"] == 0 and counts["coupled"] > 0
