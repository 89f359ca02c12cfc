"""simulate(): parameters + excitation -> SimulationResult, through the numba kernel."""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np

from dampersim.errors import InputError, SimulationDiverged
from dampersim.parameters.model import DamperSystem, Solver
from dampersim.parameters.validation import validate
from dampersim.results import SimulationResult
from dampersim.solver import _kernels as kern
from dampersim.solver.layout import build_layout, initial_state

_STATUS = {1: "NaN in the state", 2: "runaway speed", 3: "windup far beyond a hardstop"}
_COMPILED = False


def ensure_compiled(lay=None) -> float:
    """Compile (or load from numba's cache) the kernel once per process; returns the
    seconds it took, so that reported wall times exclude compilation."""
    global _COMPILED
    if _COMPILED:
        return 0.0
    from dampersim.parameters import default_parameters

    t0 = time.perf_counter()
    if lay is None:
        lay = build_layout(default_parameters(), 100.0)
    q, v = initial_state(lay)
    kern.integrate(
        q, v, np.zeros(1), lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx, lay.contacts_f,
        lay.singles, lay.pairs, lay.n_nodes, 1, 1, np.zeros((1, kern.NREC)), np.zeros((1, lay.n_nodes)),
        *kern.no_generator(),
    )
    _COMPILED = True
    return time.perf_counter() - t0


@functools.lru_cache(maxsize=32)
def _validated(system: DamperSystem) -> bool:
    validate(system)
    return True


def _validate_once(system: DamperSystem) -> None:
    """validate(), remembered per parameter set: a sweep simulates one frozen set many
    times, and the check (with its eigenvalue stability bound) costs about 1.5 ms."""
    try:
        _validated(system)
    except TypeError:  # an unhashable value inside: validate() names it, or it is fine
        validate(system)


def natural_duration(excitation, solver: Solver) -> float:
    """Duration [s]: the excitation's own length (ramps, measured records) or the solver's."""
    d = getattr(excitation, "duration", None)
    return float(d) if d is not None else float(solver.duration)


def simulate(
    system: DamperSystem,
    excitation,
    solver: Solver | None = None,
    duration: float | None = None,
    record_segments: bool = True,
) -> SimulationResult:
    """Integrate ``system`` driven by ``excitation`` (OrderSum, TorqueRamp, MeasuredTorque).

    solver: overrides ``system.solver``; duration [s]: overrides the natural duration.
    Raises ParameterError for invalid parameters and SimulationDiverged (with the time
    and a hint) if the integration blows up; it never returns a silently broken result.
    """
    if solver is not None:
        system = dataclasses.replace(system, solver=solver)
    _validate_once(system)
    sol = system.solver
    if not hasattr(excitation, "torque") or not hasattr(excitation, "speed"):
        raise InputError("excitation: accepted is an OrderSum, TorqueRamp or MeasuredTorque")
    dur = natural_duration(excitation, sol) if duration is None else float(duration)
    if not (dur > 0):
        raise InputError(f"duration = {dur!r} s: accepted is a positive duration")
    dt = sol.time_step
    nsteps = int(round(dur / dt))
    lay = build_layout(system, float(excitation.speed))
    grid = getattr(excitation, "torque_grid", None)  # fast path of excitations that have one
    if grid is not None:
        torque = grid(nsteps, dt)
    else:
        torque = np.ascontiguousarray(excitation.torque(np.arange(nsteps) * dt), dtype=np.float64)
    if not np.all(np.isfinite(torque)):
        raise InputError("excitation produced NaN/inf torque: accepted is finite torque")
    rec_every = max(1, int(round(1.0 / (sol.output_sample_rate * dt))))
    seg_every = max(1, int(round(1.0 / (sol.segment_sample_rate * dt))))
    nrec = (nsteps + rec_every - 1) // rec_every
    nseg = (nsteps + seg_every - 1) // seg_every if record_segments else 0
    rec = np.zeros((nrec, kern.NREC))
    seg = np.zeros((nseg, lay.n_nodes))
    ensure_compiled(lay)
    q, v = initial_state(lay)
    t0 = time.perf_counter()
    status, step = kern.integrate(
        q, v, torque, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx, lay.contacts_f, lay.singles, lay.pairs,
        lay.n_nodes, rec_every, seg_every, rec, seg, *kern.no_generator(),
    )
    wall = time.perf_counter() - t0
    if status != 0:
        raise SimulationDiverged(step * dt, _STATUS.get(int(status), "unknown"), dt)
    return SimulationResult.from_records(
        rec=rec,
        seg=seg,
        layout=lay,
        system=system,
        excitation=excitation,
        dt=dt,
        rec_dt=rec_every * dt,
        seg_dt=seg_every * dt,
        wall_time=wall,
    )
