"""The one place the Python side runs the compiled integrators, with arguments built from the layouts.

:func:`run_damper` marches the damper (:func:`kernels.integrate.integrate`), driven by an
input torque on the step grid and, optionally, by the coupled pulsation generator
(:class:`CoupledGenerator`); :func:`run_generator` marches the generator alone on its
stiff propshaft (:func:`kernels.engine.engine_integrate`); :func:`torque_grid` evaluates
an order sum on the step grid (:func:`kernels.excitation.order_sum`) from the
description the excitation hands over. Each raises
:class:`~dampersim.errors.SimulationDiverged` instead of returning a broken run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dampersim.errors import SimulationDiverged
from dampersim.parameters import default_parameters
from dampersim.solver.engine_layout import E_DT, NEREC, EngineLayout
from dampersim.solver.kernels.engine import engine_integrate
from dampersim.solver.kernels.excitation import order_sum
from dampersim.solver.kernels.integrate import integrate
from dampersim.solver.layout import NREC, P_DT, Layout, build_layout, initial_state

#: status codes of the integrators -> what diverged
STATUS = {1: "NaN in the state", 2: "runaway speed", 3: "windup far beyond a hardstop"}

_COMPILED = False


@dataclass(frozen=True, eq=False)
class CoupledGenerator:
    """The pulsation generator as the damper's torque source ([thesis] §4.2, rig mode).

    layout: its arrays (built with ``coupled=True``, step equal to the damper's); q, v:
    its chain state [rad], [rad/s] (advanced in place); setpoint [N m], gas [-]: mean
    torque set point and gas ramp per step; rec: its record (rows like the damper's,
    columns ER_* of :mod:`dampersim.solver.engine_layout`), written in place.
    """

    layout: EngineLayout
    q: np.ndarray
    v: np.ndarray
    setpoint: np.ndarray
    gas: np.ndarray
    rec: np.ndarray

    def arguments(self) -> tuple:
        e = self.layout
        return self.q, self.v, self.setpoint, self.gas, e.PE, e.CH, e.CYL, self.rec


def no_generator() -> tuple:
    """The generator arguments of the integrator when no pulsation generator drives the
    damper (empty arrays of the right types)."""
    z1 = np.zeros(0)
    return z1, z1, z1, z1, z1, np.zeros((0, 4)), np.zeros((0, 2)), np.zeros((0, NEREC))


def _integrate(lay: Layout, q, v, torque, rec_every, seg_every, rec, seg, generator: CoupledGenerator | None):
    """The integrator's one call: damper arrays from ``lay``, generator arguments from
    ``generator`` or the no-generator placeholders. Returns (status, step)."""
    gen = no_generator() if generator is None else generator.arguments()
    return integrate(
        q, v, torque, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx, lay.contacts_f, lay.singles, lay.pairs,
        lay.n_nodes, rec_every, seg_every, rec, seg, *gen,
    )


def ensure_compiled(lay: Layout | None = None) -> float:
    """Compile (or load from numba's cache) the integrator once per process; returns the
    seconds it took, so that reported wall times exclude compilation."""
    global _COMPILED
    if _COMPILED:
        return 0.0
    t0 = time.perf_counter()
    if lay is None:
        lay = build_layout(default_parameters(), 100.0)
    q, v = initial_state(lay)
    _integrate(lay, q, v, np.zeros(1), 1, 1, np.zeros((1, NREC)), np.zeros((1, lay.n_nodes)), None)
    _COMPILED = True
    return time.perf_counter() - t0


@dataclass(frozen=True, eq=False)
class DamperRun:
    """What :func:`run_damper` returns: the record (columns R_*), the segment samples
    (slot coordinates of every node) and the wall time [s] of the integration alone."""

    rec: np.ndarray
    seg: np.ndarray
    wall_time: float


def run_damper(lay: Layout, torque: np.ndarray, rec_every: int, nrec: int, seg_every: int = 1, nseg: int = 0,
               generator: CoupledGenerator | None = None) -> DamperRun:
    """March the damper from its unloaded start (:func:`initial_state`) ``len(torque)``
    steps of the layout's step dt, with input torque ``torque`` [N m] at t = n dt (plus
    the coupled generator's link torque when ``generator`` is given); ``nrec`` records
    every ``rec_every`` steps, ``nseg`` segment samples every ``seg_every`` steps."""
    torque = np.ascontiguousarray(torque, dtype=np.float64)
    ensure_compiled(lay)
    rec = np.zeros((nrec, NREC))
    seg = np.zeros((nseg, lay.n_nodes))
    q, v = initial_state(lay)
    t0 = time.perf_counter()
    status, step = _integrate(lay, q, v, torque, rec_every, seg_every, rec, seg, generator)
    wall = time.perf_counter() - t0
    _check(status, step, float(lay.P[P_DT]))
    return DamperRun(rec, seg, wall)


def run_generator(lay: EngineLayout, setpoint: np.ndarray, gas: np.ndarray, rec_every: int, rec: np.ndarray) -> float:
    """March the pulsation generator alone from rest on its stiff propshaft to a held
    output dyno ([thesis] §4.3.1), ``len(setpoint)`` steps of the layout's step; writes
    ``rec`` (columns ER_*) every ``rec_every`` steps. Returns the wall time [s]."""
    q = np.zeros(len(lay.CH))
    v = np.zeros(len(lay.CH))
    t0 = time.perf_counter()
    status, step = engine_integrate(q, v, setpoint, gas, lay.PE, lay.CH, lay.CYL, rec_every, rec)
    wall = time.perf_counter() - t0
    _check(status, step, float(lay.PE[E_DT]))
    return wall


def _check(status, step, dt) -> None:
    if status != 0:
        raise SimulationDiverged(step * dt, STATUS.get(int(status), "unknown"), dt)


def torque_grid(source, n: int, dt: float) -> np.ndarray:
    """An order sum's input torque [N m] at t = 0, dt, ..., (n-1) dt [s] (the step grid),
    from one compiled pass (:func:`kernels.excitation.order_sum`); equal to the
    excitation's NumPy ``torque(np.arange(n) * dt)`` to rounding, in a fraction of the time.

    source: the description of the order sum (:class:`dampersim.excitation.orders.OrderSpec`:
    speed, mean torque, ramps, orders, amplitudes, phases), or an excitation that hands
    one over through ``order_spec()``.
    """
    spec = source.order_spec() if hasattr(source, "order_spec") else source
    out = np.empty(int(n))
    k, a, ph = (np.ascontiguousarray(x, dtype=np.float64) for x in (spec.orders, spec.amplitudes, spec.phases))
    order_sum(out, float(dt), float(spec.speed), float(spec.mean_torque), float(spec.mean_ramp),
              float(spec.amplitude_ramp), k, a, ph)
    return out


def input_torque(excitation, n: int, dt: float) -> np.ndarray:
    """The excitation's input torque [N m] on the step grid: compiled for an excitation
    that describes an order sum (``order_spec()``), else its own ``torque(t)``."""
    if hasattr(excitation, "order_spec"):
        return torque_grid(excitation, n, dt)
    return np.ascontiguousarray(excitation.torque(np.arange(n) * dt), dtype=np.float64)


__all__ = ["STATUS", "CoupledGenerator", "DamperRun", "no_generator", "ensure_compiled", "run_damper", "run_generator",
           "torque_grid", "input_torque"]
