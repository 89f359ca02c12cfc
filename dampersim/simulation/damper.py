"""simulate(): parameters + excitation -> SimulationResult, through the solver's driver."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from dampersim.errors import InputError
from dampersim.parameters.model import DamperSystem, Solver
from dampersim.parameters.validation import validate
from dampersim.results import SimulationResult
from dampersim.solver.driver import input_torque, run_damper
from dampersim.solver.layout import build_layout
from dampersim.solver.linear import check_time_step


@functools.lru_cache(maxsize=32)
def _validated(system: DamperSystem) -> bool:
    check_time_step(validate(system))
    return True


def _validate_once(system: DamperSystem) -> None:
    """validate() and the solver's stability check, remembered per parameter set: a sweep
    simulates one frozen set many times, and the eigenvalue bound costs about 1.5 ms."""
    try:
        _validated(system)
    except TypeError:  # an unhashable value inside: validate() names it, or it is fine
        check_time_step(validate(system))


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
    torque = input_torque(excitation, nsteps, dt)
    if not np.all(np.isfinite(torque)):
        raise InputError("excitation produced NaN/inf torque: accepted is finite torque")
    rec_every = max(1, int(round(1.0 / (sol.output_sample_rate * dt))))
    seg_every = max(1, int(round(1.0 / (sol.segment_sample_rate * dt))))
    nrec = (nsteps + rec_every - 1) // rec_every
    nseg = (nsteps + seg_every - 1) // seg_every if record_segments else 0
    run = run_damper(lay, torque, rec_every, nrec, seg_every, nseg)
    return SimulationResult.from_records(
        rec=run.rec,
        seg=run.seg,
        layout=lay,
        system=system,
        excitation=excitation,
        dt=dt,
        rec_dt=rec_every * dt,
        seg_dt=seg_every * dt,
        wall_time=run.wall_time,
    )
