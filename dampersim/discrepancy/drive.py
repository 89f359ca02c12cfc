"""Drive a parameter set with measured test points (the compare step's simulations).

Task functions are module level and take plain picklable arguments so they run in the
sweeps' process pool (:func:`dampersim.sweeps.backends.process_pool`). A run that fails (an
exception, a diverged integration, a non-finite result) comes back as {"error": text}, and
the diagnosis reads it as a failure, never as numbers.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from dampersim.discrepancy import tracking
from dampersim.excitation import MeasuredTorque
from dampersim.signal import lowpass_first_order
from dampersim.simulation import simulate
from dampersim.solver.linear import max_stable_time_step
from dampersim import jobs
from dampersim.sweeps.backends import process_pool

ORDERS = tuple(float(k) for k in range(1, 9))
RAMP_FILTER_HZ = 10.0  # [thesis] §3.4: loops low-passed at 10 Hz
#: time [s] the model runs on the looped record at full amplitude after the thesis's 0.6 s
#: start-up, before the record begins: a rig records in steady running, and the start-up
#: leaves a transient of a lightly damped low-frequency mode of damper and rig. Measured
#: against noise-free synthetic records of the model itself, taken 1 s after their start-up
#: (``python bench/bench_drive_startup.py --points tc_1600 tc_2800 map_900_150 map_1200_50
#: map_1500_350 --settle S``): the largest order errors were 0.61 N m (order 2, 23 N m, at
#: 1500 rpm and 350 N m) and 0.44 N m (order 6, 10.4 N m, at 2800 rpm) with S = 0, and 0.13
#: and 0.11 N m with S = 0.5. 0.5 s costs 31 % more simulated time per run (2.1 s for a 1 s
#: record); what it leaves is about 1 % of an order.
DRIVE_SETTLE = 0.5


@dataclass(frozen=True, eq=False)
class RecordedRamp:
    """A measured ramp torque as the drive, played as recorded (the model starts unloaded,
    as the rig's ramps do). speed [rad/s]; time [s]; torque_samples [N m]."""

    speed: float
    time: np.ndarray = field(repr=False)
    torque_samples: np.ndarray = field(repr=False)

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    steady_start = 0.0

    def torque(self, t):
        return np.interp(np.asarray(t, dtype=float), self.time - self.time[0], self.torque_samples)


def diagnosis_system(system):
    """``system`` with its own time step, lowered to 98 % of the stability bound where a
    calibration trial (inertias down, stiffnesses up) has moved the bound below it.

    The diagnosis runs at the parameter set's step (the default 1/120 000 s, the largest
    that passes the accuracy grid of docs/model.md §12 away from knee points with
    several steady states): a coarser one (4e-5 s was tried) left 1-3 % integration
    error on the excited orders at high speed and torque, a systematic gap of the order
    of the noise floor that no effect explains.
    """

    dt = min(system.solver.time_step, 0.98 * max_stable_time_step(system))
    return dataclasses.replace(system, solver=dataclasses.replace(system.solver, time_step=dt))


def rezeroed(point, offset_nm: float = 0.0, gain: float = 1.0):
    """``point`` with its input torque channel corrected for a zero offset ``offset_nm``
    [N m] and a gain ``gain`` [-] (recorded = gain x true + offset, so true = (recorded -
    offset) / gain); the output channel, which the likelihood compares, is left as it is.
    The point itself when there is nothing to correct."""
    if offset_nm == 0.0 and gain == 1.0:
        return point
    return dataclasses.replace(point, input_torque=(np.asarray(point.input_torque) - offset_nm) / gain)


def simulate_point(system, point, halves: bool = False) -> dict:
    """Simulate one measured point with ``system``.

    torsional: {"orders": output order amplitudes [N m] over the record's revolutions, read
    on the record's measured angle like the measured output, "coefficients": the same as
    complex coefficients (:func:`tracking.driven_coefficients`), and with ``halves`` "halves":
    the coefficients over each half of the record, read like the measured halves
    (:func:`tracking.half_coefficients`, for the repeatability of the residual)};
    ramp: {"torque", "windup"} on the record's time base (windup [rad]).
    """

    if point.kind == "torsional":
        ex = MeasuredTorque(point.speed, point.time, point.input_torque, settle=DRIVE_SETTLE)
        res = simulate(system, ex, record_segments=False)
        c = tracking.driven_coefficients(point, res, ex.steady_start, ORDERS)
        out = {"orders": np.abs(c), "coefficients": c}
        if halves:
            model_output = tracking.driven_output(point, res, ex.steady_start)
            out["halves"] = tracking.half_coefficients(point, model_output, ORDERS)
        return out
    ex = RecordedRamp(point.speed, point.time, point.input_torque)
    res = simulate(system, ex, record_segments=False)
    wind = np.interp(point.time, res.t, res.windup_total)
    return {"windup": wind}


def run_task(args) -> dict:
    """:func:`simulate_point` of ``args`` = (system, point) or (system, point, halves), or
    {"error": text} when the run raised or gave a non-finite result (a diverged run must not
    read as numbers)."""
    system, point, *rest = args
    try:
        out = simulate_point(system, point, *rest)
    except Exception as exc:  # noqa: BLE001 - a failed point is reported, not fatal
        return {"error": f"{type(exc).__name__}: {exc}"}
    bad = [k for k, v in out.items() if not np.all(np.isfinite(np.asarray(v)))]
    if bad:
        return {"error": f"non-finite {', '.join(bad)}: the run diverged"}
    return out


class Runner:
    """Runs (system, point) tasks serially or in a process pool; counts simulations.

    ``workers`` None: up to 2 processes, fewer when the cores are shared with other
    running jobs (:func:`dampersim.jobs.sweep_workers`; all cores count when no job runs,
    as on the command line)."""

    def __init__(self, workers: int | None = None, progress=None):
        self.workers = max(1, int(workers if workers is not None else min(2, jobs.sweep_workers())))
        self.progress = progress
        self.count = 0
        self._pool = None

    def __enter__(self):
        if self.workers > 1:
            self._pool = process_pool(self.workers)
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def map(self, tasks, fn=None) -> list:
        """``fn`` (default :func:`run_task`, a module-level function) of every task."""
        fn = fn or run_task
        tasks = list(tasks)
        self.count += len(tasks)
        if self._pool is None:
            return [fn(t) for t in tasks]
        return list(self._pool.map(fn, tasks, chunksize=max(1, len(tasks) // (4 * self.workers))))


def coefficients_of(runner, system, points, errors: dict | None = None, halves: dict | None = None) -> np.ndarray:
    """Complex output order coefficients [N m] of ``system`` driven by each torsional point
    (at :func:`diagnosis_system`'s step); a failed run gives a row of complex NaN, never
    numbers, and its message goes into ``errors[row]`` when a dict is given. ``halves``, when
    a dict is given, receives each run's coefficients over the record's two halves
    (``halves[row]``, shape (2, orders))."""
    return coefficients_of_sets(runner, [system], points, None if errors is None else [errors],
                                None if halves is None else [halves])[0]


def coefficients_of_sets(runner, systems, points, errors: list | None = None, halves: list | None = None) -> np.ndarray:
    """:func:`coefficients_of` of several parameter sets over the same points in one map of
    the runner (no wait for the pool to drain between the sets): shape (sets, points,
    orders); ``errors`` and ``halves``, when given, hold one dict per set."""
    extra = (True,) if halves is not None else ()
    tasks = [(sysd, p, *extra) for sysd in map(diagnosis_system, systems) for p in points]
    out = runner.map(tasks)
    rows = np.full((len(systems), len(points), len(ORDERS)), np.nan + 1j * np.nan)
    for n, r in enumerate(out):
        k, i = divmod(n, len(points))
        if "coefficients" in r:
            rows[k, i] = r["coefficients"]
            if halves is not None:
                halves[k][i] = r["halves"]
        elif errors is not None:
            errors[k][i] = r.get("error", "no result")
    return rows


def run_problem(point, why: str) -> dict:
    """A campaign ``problems`` entry (file, field "model", point id, message) for a point
    whose model run failed."""
    return {"file": point.file, "field": "model", "point": point.id, "message": why}


def failed_text(failed: dict) -> str:
    """'p3, p7 (first message)' for {point id: message} of failed runs."""
    if not failed:
        return "no run completed"
    return f"{', '.join(sorted(failed))} ({next(iter(failed.values()))})"


def windup_error_deg(sim_windup, point) -> float:
    """RMS difference [deg] of the 10 Hz low-passed simulated and measured windup."""

    fs = point.sample_rate_hz
    a = lowpass_first_order(sim_windup, fs, min(RAMP_FILTER_HZ, 0.45 * fs))
    b = lowpass_first_order(point.windup, fs, min(RAMP_FILTER_HZ, 0.45 * fs))
    return float(math.degrees(np.sqrt(np.mean((a - b) ** 2))))


__all__ = ["ORDERS", "DRIVE_SETTLE", "RecordedRamp", "rezeroed", "diagnosis_system", "simulate_point",
           "run_task", "Runner", "coefficients_of", "coefficients_of_sets", "run_problem", "failed_text",
           "windup_error_deg"]
