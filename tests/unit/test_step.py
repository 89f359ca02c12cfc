"""The production step alone: N calls of kernels.integrate.step reproduce integrate.

integrate() marches the damper by calling step() once per step (plus records and the
divergence check); calling step() from Python N times with the same state must give the
same numbers bit for bit, so that step() can be examined on its own as what production
runs.
"""

from __future__ import annotations

import numpy as np
import pytest

import dampersim as ds
from dampersim.discrepancy.effects import with_effect
from dampersim.parameters import with_updates
from dampersim.solver.driver import input_torque, no_generator
from dampersim.solver.kernels.integrate import integrate, step, workspace
from dampersim.solver.layout import NREC, S_SIZE, build_layout, initial_state
from dampersim.units import rpm_to_rad_s

N = 6000  # 0.05 s at the default step: the ramps end and the hardstop closes


def _cases():
    p = ds.default_parameters()
    heavy = ds.OrderSum(speed=rpm_to_rad_s(1500), mean_torque=550.0, orders=((2, 300.0, 0.0),),
                        mean_ramp=0.01, amplitude_ramp=0.01)
    light = ds.OrderSum(speed=rpm_to_rad_s(1500), mean_torque=200.0, orders=((2, 300.0, 0.0), (4, 100.0, 0.0)),
                        mean_ramp=0.01, amplitude_ramp=0.01)
    yield "default", p, light
    yield "hardstops", p, heavy  # the outer stop closes and releases within N steps
    yield "stacking", with_updates(p, {"hardstops.enabled": False}), heavy
    yield "clutch", with_effect(p, "clutch_slip", {"capacity": 300.0}), heavy


@pytest.mark.parametrize("name,system,ex", list(_cases()), ids=[c[0] for c in _cases()])
def test_n_steps_equal_integrate(name, system, ex):
    lay = build_layout(system, ex.speed)
    dt = system.solver.time_step
    torque = input_torque(ex, N, dt)
    seg_every = 7  # a segment sample every 7 steps, a record every step

    # production: the integration loop
    q1, v1 = initial_state(lay)
    rec1 = np.zeros((N, NREC))
    seg1 = np.zeros(((N + seg_every - 1) // seg_every, lay.n_nodes))
    status, done = integrate(q1, v1, torque, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx, lay.contacts_f,
                             lay.singles, lay.pairs, lay.n_nodes, 1, seg_every, rec1, seg1, *no_generator())
    assert (status, done) == (0, N)

    # the same steps, one call each
    q2, v2 = initial_state(lay)
    vprev = v2.copy()
    S = np.zeros(S_SIZE)
    W = workspace(lay.J, lay.n_nodes, len(lay.contacts_idx), len(lay.singles), len(lay.pairs))
    rec2 = np.zeros((N, NREC))
    seg2 = np.zeros_like(seg1)
    empty = np.zeros(0)
    for n in range(N):
        segrow = seg2[n // seg_every] if n % seg_every == 0 else empty
        step(n * dt, torque[n], q2, v2, vprev, S, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx,
             lay.contacts_f, lay.singles, lay.pairs, rec2[n], segrow, W)

    np.testing.assert_array_equal(q2, q1)
    np.testing.assert_array_equal(v2, v1)
    np.testing.assert_array_equal(rec2, rec1)
    np.testing.assert_array_equal(seg2, seg1)
    if name == "hardstops":
        assert np.abs(rec1[:, 10]).max() > 0.0  # R_HS_O: the stop did close
    if name == "stacking":
        assert rec1[-1, 19] > 0.0  # R_E_STACK: coil stacking did happen
