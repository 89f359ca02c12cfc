"""Cost of a request, estimated before anything is allocated, and the server's budgets.

Every run of the damper model marches ``steps = duration / solver.time_step`` steps of a
state of ``DOF`` degrees of freedom, and the kernel's time is close to proportional to
their product. A request's *work* is therefore counted in step·DOF and its memory in
bytes [B], both from the parameter set alone (no layout, no array is built):

* DOF (:func:`degrees_of_freedom`), as :func:`dampersim.solver.layout.build_layout` lays
  them out: the three damper inertias, ``segments - 1`` masses per integrated spring
  (outer spring; nested pair outer; nested pair inner when the set has one; the short
  pair's two springs with effect inner_short_springs), one DOF per rig element, plus
  the clutch drive side and the pendulum absorber when those effects are on. The
  segment record holds ``segments + 1`` nodes per spring.
* bytes of one run (:func:`point_cost`), as :func:`dampersim.simulation.simulate`
  allocates them: the input torque on the step grid (8 B per step, the largest array when
  the step is small), the integrator's record (``NREC`` channels at the output sample
  rate) and the result's copies of its columns, the segment record (nodes at the segment
  sample rate) and the state vectors.

Measured rate (``python bench/bench_cost_rate.py``: whole runs of each kind the server
admits by estimate, estimated work over measured wall time, one core, warm kernels): 1.6e7
to 4.0e7 step·DOF per second on the 2-core development machine, whose speed moves by up
to about 1.8 times within an hour (three runs within half an hour: a diagnosis model run
1.6e7, 2.9e7 and 2.7e7, a test point as the Explorer runs it 1.8e7, 2.2e7 and 2.0e7, a
30 s ramp 2.3e7, 4.0e7 and 2.9e7; commit 3c38a79's library; a fourth run, pinned to one
core and with the coupled pulsation run, on 4eaf555: 1.7e7 to 2.4e7 over its seven
kinds). :data:`STEP_DOF_PER_SECOND` takes the slowest, rounded down, 1.5e7, so a time
estimate errs long, by up to about 2.7 times when the machine runs fast. It was 5e7
before, from 18.6 ns per step·DOF measured before the fitted friction step and on a
faster day, and time estimates read up to about 3 times short (1.25 to 3.1 times over the
kinds measured).

The budgets are work, not time, and kept their values when the rate was corrected:
:data:`DEFAULT_AUTOSTART` 2.5e9 step·DOF (about 2.8 min of one core at the rate: every
default page state, the largest being the Maps page's 80 points at 2.15e9 with the default
48/16 segments, starts by itself) and :data:`DEFAULT_LIMIT` 7.5e10 step·DOF (about 83 min of
one core at the rate: the bundled example campaign's diagnosis, bounded at 7.31e10 by
:func:`diagnosis_cost`, is admitted, 2.5 % below it, and took 878 s on 2 idle cores for 1872
of its then 3039 bounded runs, now 3391; the limit was 7e10 until the magnitude grid's
continuation added 168 bounded runs, and the pair's partner screen added 80 more and the
partner's count choice 24 (a fit on top of another effect no longer repeating its best run
saves 8; the partner screen's absorber tuning orders add 16); it applies
to every kind of request). Both are server
settings, read from the environment at call time (:func:`budgets`): ``DAMPERSIM_BUDGET``
and ``DAMPERSIM_AUTOSTART_BUDGET`` in step·DOF, ``DAMPERSIM_MEMORY_BUDGET`` in bytes
(default 1 GiB).

:func:`admit` applies them: above the limit a :class:`BudgetError` (an
:class:`~dampersim.errors.InputError`) gives the estimate and the limit; above the
autostart budget the answer is ``"ask"`` (a page shows the estimate and waits for its
Run button); else ``"run"``.
"""

from __future__ import annotations

import math
import os
import threading
from contextlib import contextmanager
from dataclasses import dataclass

from dampersim.errors import InputError
from dampersim.solver.layout import NREC

#: Kernel speed [step·DOF per second of one core]: the slowest whole-run rate measured, rounded
#: down (the module docstring).
STEP_DOF_PER_SECOND = 1.5e7
#: Most work [step·DOF] a page computes in the request thread while the browser waits
#: (Explorer, Segments), whatever the server's budget: about 3.3 min of one core at
#: STEP_DOF_PER_SECOND, 1.3 to 3.1 min at the rates measured (the module docstring), so one
#: such request holds its thread for a few minutes at most. It was set as 60 s at the old
#: rate of 5e7 and kept when the rate was corrected: above DEFAULT_AUTOSTART, so a point
#: between the two waits for its Run button, and above the Explorer's largest repeat at the
#: default duration (32 runs of the default point, 8.6e8; with the spread check 96 runs'
#: worth, 2.6e9, which waits for Run). Larger points belong to the command line
#: (``dampersim simulate``). How many run at once is bounded separately by
#: :func:`foreground_slot`, so they never take every request thread.
FOREGROUND_WORK = 3.0e9
#: Foreground computations running at once in one server process, by default: half of
#: ``app.py``'s 8 request threads, so the other half always answers page loads, cache
#: hits, job polls and static files. Setting: ``DAMPERSIM_FOREGROUND_SLOTS`` (read at
#: call time; ``python app.py`` sets it to half of ``--threads`` unless it is set).
DEFAULT_FOREGROUND_SLOTS = max(1, 8 // 2)
FOREGROUND_SLOTS_ENV = "DAMPERSIM_FOREGROUND_SLOTS"
#: Default autostart budget [step·DOF]: about 2.8 min of one core at STEP_DOF_PER_SECOND.
DEFAULT_AUTOSTART = 2.5e9
#: Default limit [step·DOF]: about 83 minutes of one core at STEP_DOF_PER_SECOND.
DEFAULT_LIMIT = 7.5e10
#: Default memory limit of one request [B]: 1 GiB.
DEFAULT_BYTES_LIMIT = float(2**30)
#: Environment variables of the budgets (read by :func:`budgets` at call time).
BUDGET_ENV = "DAMPERSIM_BUDGET"
AUTOSTART_ENV = "DAMPERSIM_AUTOSTART_BUDGET"
BYTES_ENV = "DAMPERSIM_MEMORY_BUDGET"

#: Columns a :class:`~dampersim.results.SimulationResult` copies out of the record
#: (time, torques, speeds, windups, hardstops, motor, set torques, energies).
RESULT_COLUMNS = 21
#: Bytes of one float64 value.
_F8 = 8
#: Top of the stored spectra of a sweep point [Hz] (:mod:`dampersim.sweeps.cache`) and
#: the bytes of one bin (float32, input and output).
_SPECTRUM_TOP_HZ = 1000.0
_SPECTRUM_BIN_BYTES = 2 * 4
#: Analysis window of a sweep point [s] when none is given ([thesis] 1.25 s).
_WINDOW_S = 1.25


@dataclass(frozen=True)
class Cost:
    """Estimated cost of a request: ``work`` [step·DOF], ``bytes`` [B] (peak memory of the
    arrays it allocates) and ``what`` (a short description for messages).

    Costs add up (``a + b``): work and bytes both sum, an upper bound for runs made one
    after the other.
    """

    work: float
    bytes: float
    what: str = "this request"

    def __add__(self, other: "Cost") -> "Cost":
        if not isinstance(other, Cost):
            return NotImplemented
        what = self.what if self.what == other.what else f"{self.what} and {other.what}"
        return Cost(self.work + other.work, self.bytes + other.bytes, what)

    def seconds(self) -> float:
        """Rough compute time [s] on one core (:data:`STEP_DOF_PER_SECOND`)."""
        return self.work / STEP_DOF_PER_SECOND

    def duration(self) -> str:
        """:meth:`seconds` as short text: "4 min"."""
        return work_duration(self.work)

    def text(self) -> str:
        """"about 3.1e8 step·DOF and 120 MB"."""
        return f"about {_work_text(self.work)} step·DOF and {bytes_text(self.bytes)}"


def _work_text(work: float) -> str:
    return f"{work:.1e}".replace("e+0", "e").replace("e+", "e")


def bytes_text(n: float) -> str:
    """Bytes as short text, decimal units: "120 MB", "16 GB", "512 B"."""
    n = float(n)
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            v = n / size
            return f"{v:.0f} {unit}" if v >= 10 else f"{v:.1f} {unit}"
    return f"{n:.0f} B"


def work_duration(work: float) -> str:
    """The time ``work`` [step·DOF] takes one core at :data:`STEP_DOF_PER_SECOND`, as short
    text: "4 min"."""
    return duration_text(work / STEP_DOF_PER_SECOND)


def duration_text(seconds: float) -> str:
    """Seconds as "25 s", "4 min", "3.2 h"."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


# --------------------------------------------------------------------------- counting
def degrees_of_freedom(system) -> int:
    """Size of the integrated state [-] of ``system`` (see the module docstring); equal to
    ``build_layout(system, speed).ndof``."""
    s = system
    no, ni = int(s.solver.outer_segments), int(s.solver.inner_segments)
    nested = s.inner.nested is not None
    dof = 3 + (no - 1) + (ni - 1) + ((ni - 1) if nested else 0) + len(s.rig.elements)
    dof += 2 * (ni - 1) * int(s.short_pairs > 0)  # the short pair (effect inner_short_springs)
    dof += int(bool(s.effects.clutch_slip.enabled)) + int(bool(s.effects.pendulum_absorber.enabled))
    return dof


def segment_nodes(system) -> int:
    """Nodes of the segment record [-]: ``segments + 1`` per integrated spring; equal to
    ``build_layout(system, speed).n_nodes``."""
    no, ni = int(system.solver.outer_segments), int(system.solver.inner_segments)
    short = 2 * (ni + 1) if system.short_pairs > 0 else 0  # the short pair (effect inner_short_springs)
    return (no + 1) + (ni + 1) + ((ni + 1) if system.inner.nested is not None else 0) + short


def _steps(duration: float, dt: float) -> float:
    """Steps of a run (a float: a hostile duration may give a count too large to hold)."""
    duration, dt = float(duration), float(dt)
    if not (math.isfinite(duration) and duration > 0):
        raise InputError(f"duration = {duration!r} s: accepted is a positive finite duration")
    if not (math.isfinite(dt) and dt > 0):
        raise InputError(f"solver.time_step = {dt!r} s: accepted is a positive finite step")
    return max(1.0, round(duration / dt))


def _samples(steps: float, rate: float, dt: float) -> float:
    """Samples kept of ``steps`` steps at ``rate`` [Hz], as :func:`simulate` decimates."""
    every = max(1.0, round(1.0 / (float(rate) * dt)))
    return math.ceil(steps / every)


def run_bytes(system, duration: float, record_segments: bool = True) -> float:
    """Peak bytes [B] of the arrays one :func:`~dampersim.simulation.simulate` run of
    ``duration`` [s] allocates (see the module docstring)."""
    sol = system.solver
    dt = float(sol.time_step)
    steps = _steps(duration, dt)
    nrec = _samples(steps, sol.output_sample_rate, dt)
    dof = degrees_of_freedom(system)
    total = steps * _F8  # input torque on the step grid
    total += nrec * (NREC + RESULT_COLUMNS) * _F8  # record + the result's column copies
    if record_segments:
        nseg = _samples(steps, sol.segment_sample_rate, dt)
        total += nseg * (segment_nodes(system) + 1) * _F8  # node record + its time axis
    total += 4 * dof * _F8  # q, v and the kernel's scratch vectors
    return float(total)


# --------------------------------------------------------------------------- requests
def point_cost(system, duration: float, record_segments: bool = True, what: str = "this test point") -> Cost:
    """One test point of ``duration`` [s]: ``steps x DOF`` and :func:`run_bytes`."""
    steps = _steps(duration, system.solver.time_step)
    return Cost(steps * degrees_of_freedom(system), run_bytes(system, duration, record_segments), what)


def sweep_cost(system, n_points: int, duration: float, window: float = _WINDOW_S, workers: int | None = None,
               what: str | None = None) -> Cost:
    """A sweep of ``n_points`` test points of ``duration`` [s] each (no segment record,
    as :mod:`dampersim.sweeps` runs them): the points' work; the bytes of ``workers``
    points in flight (default: the cores) plus every point's stored spectra (input and
    output, float32, up to 1 kHz at the resolution 1 / ``window`` [s])."""
    n = max(0, int(n_points))
    one = point_cost(system, duration, record_segments=False)
    workers = max(1, int(workers or _cores()))
    bins = _SPECTRUM_TOP_HZ * float(window) + 1
    bytes_ = min(n, workers) * one.bytes + n * bins * _SPECTRUM_BIN_BYTES
    return Cost(n * one.work, float(bytes_), what or f"a sweep of {n} test point{'s' if n != 1 else ''}")


def ramp_cost(system, duration: float, n_speeds: int = 1, what: str | None = None) -> Cost:
    """Hysteresis ramps: ``n_speeds`` runs of ``duration`` [s] each (the protocol's own
    length: its torque span over the rate plus the holds, see
    :func:`dampersim.excitation.ramp_protocol`), one after the other; bytes of one run
    plus the loops kept (six series per speed at the output sample rate)."""
    n = max(0, int(n_speeds))
    one = point_cost(system, duration, record_segments=False)
    steps = _steps(duration, system.solver.time_step)
    kept = n * 6 * _samples(steps, system.solver.output_sample_rate, float(system.solver.time_step)) * _F8
    return Cost(n * one.work, one.bytes + kept,
                what or f"{n} ramp{'s' if n != 1 else ''} of {duration:.0f} s simulated time")


#: Work of one pulsation-generator DOF per step, in damper step·DOF: each generator DOF
#: carries a crank section with its cylinder (gas law, ring and bearing friction), so it
#: costs more than a damper DOF. Measured by ``python bench/bench_cost_rate.py`` (default
#: generator alone, 2.6 s at 1e-5 s, 8 DOF, 1500 rpm, against a sweep point and a diagnosis
#: run at 48/16 in the same process): 0.93 to 1.40 times a damper DOF-step in four runs,
#: rounded up to 1.5 so the estimate errs long. (It was 3.5, measured against the damper's
#: kernel-only 5.3e7 to 5.9e7 step·DOF per second, before the fitted friction step made the
#: damper's step about 45 % dearer and on a faster day; the rest of the fall was not
#: separated.)
GENERATOR_DOF_WEIGHT = 1.5


def pulsation_cost(coupled: bool = False, runs: int = 1, system=None, generator=None, duration: float | None = None,
                   time_step: float | None = None, sample_rate: float | None = None, what: str | None = None) -> Cost:
    """``runs`` runs of the pulsation generator
    (:func:`dampersim.simulation.simulate_pulsation`, one after the other), alone or
    ``coupled`` to the damper and rig (``system``, default parameters), with that
    function's defaults for ``duration`` [s], ``time_step`` [s] and ``sample_rate`` [Hz]
    where not given. Work [step·DOF]: steps x (the generator's DOF, one per element of its
    chain, weighted by :data:`GENERATOR_DOF_WEIGHT`, plus the damper's DOF when coupled).
    Bytes [B] of one run: time, set-point and gas-scale arrays on the step grid, the
    generator's record and, coupled, the damper's input grid and record."""
    import inspect

    from dampersim.parameters import default_parameters
    from dampersim.parameters.engine import default_pulsation_generator
    from dampersim.simulation.pulsation import simulate_pulsation
    from dampersim.solver.engine_layout import NEREC

    defaults = {k: p.default for k, p in inspect.signature(simulate_pulsation).parameters.items()}
    duration = float(defaults["duration"] if duration is None else duration)
    dt = float(defaults["time_step"] if time_step is None else time_step)
    rate = float(defaults["sample_rate"] if sample_rate is None else sample_rate)
    steps = _steps(duration, dt)
    nrec = _samples(steps, rate, dt)
    pg = generator if generator is not None else default_pulsation_generator()
    dof = GENERATOR_DOF_WEIGHT * len(pg.chain)
    total = 3 * steps * _F8 + nrec * NEREC * _F8  # t, set point, gas scale; the generator's record
    if coupled:
        system = system if system is not None else default_parameters()
        dof += degrees_of_freedom(system)
        total += steps * _F8 + nrec * NREC * _F8 + 4 * degrees_of_freedom(system) * _F8
    n = max(1, int(runs))
    label = what or (f"{n} pulsation generator run{'s' if n != 1 else ''}" + (" coupled to the damper" if coupled else ""))
    return Cost(float(n * steps * dof), float(total), label)


# Counts of :func:`dampersim.discrepancy.diagnose.diagnose` (its defaults), kept here because
# the discrepancy package sits above this module; tests check them against it.
DIAGNOSIS_FACTORS = 6  # calibrated log scale factors (CALIBRATION)
DIAGNOSIS_COMPARE_RUNS = 4 + 2 * 3  # per point: as given, coarse, input moved up and down (input_mean_sd),
# and the set moved up and down along each of the three directions the calibration cannot follow
#: per point at the calibrated set: the compare step's checks again, without the set's own run
#: (diagnose, step 2b; model_terms.RUNS_PER_POINT)
DIAGNOSIS_RECHECK_RUNS = DIAGNOSIS_COMPARE_RUNS - 1
DIAGNOSIS_SCAN = 4  # coarse-scan steps per factor (CAL_SCAN)
DIAGNOSIS_ITERATIONS = 6  # Gauss-Newton iterations (calibration_iterations)
DIAGNOSIS_DERIVATIVE_STEPS = 2  # sensitivity steps an iteration may try in turn (fitting.CAL_DERIVATIVE_STEPS)
# (the naming's 5 % sensitivities are taken again after the iterations only when the last one
# moved the factors with the 1 % step alone, leaving one of its two sets untaken: never more
# than two sets per iteration in all)
DIAGNOSIS_STEP_TRIALS = 3  # step lengths tried per iteration (CAL_STEP_FRACTIONS)
DIAGNOSIS_SHORTLIST = 3  # candidates fitted after the screen (shortlist)
#: magnitude grid + its continuation beyond an end (at most 3) + bounded refinement + verification + derivative runs
DIAGNOSIS_FIT_RUNS = 5 + 3 + 8 + 3 + 1
DIAGNOSIS_STARTS = 2  # starting points per candidate (calibrated, estimated)
#: screen runs per start beyond one per candidate: the short springs are read at 4 clearances
#: (discrepancy.shapes.SCREEN_FACTORS), the other effects at their own shape
DIAGNOSIS_SCREEN_EXTRA = 4 - 1
#: the partner screen's runs beyond one per candidate: the short springs at 4 clearances and the
#: pendulum absorber at 3 tuning orders (discrepancy.shapes.partner_grid)
DIAGNOSIS_PARTNER_EXTRA = DIAGNOSIS_SCREEN_EXTRA + (3 - 1)
#: runs before a shortlisted candidate's fit that choose its discrete shape: the short springs'
#: 1 to 3 springs (discrepancy.shapes.SCREEN_CHOICES; naming.Namer.choose)
DIAGNOSIS_CHOICE_RUNS = 3
DIAGNOSIS_SHAPE_RUNS = 2 + 1  # at most two shape parameters' derivatives + the trial (naming.SHAPES)
#: a pair's second magnitude: grid + its continuation + refinement + derivative (on top of the
#: leading fit the search's own run at the best magnitude is its verification). The second
#: effect itself is chosen by screening every other candidate once on top of the leading fit,
#: discrepancy.partner.gains, the short springs and the absorber at DIAGNOSIS_PARTNER_EXTRA more
#: shapes, and the springs' count by DIAGNOSIS_CHOICE_RUNS more, discrepancy.partner.shape:
#: counted apart in :func:`diagnosis_runs`
DIAGNOSIS_PAIR_RUNS = 5 + 3 + 8 + 1
DIAGNOSIS_REFIT_ITERATIONS = 3  # Gauss-Newton iterations of naming.Namer.refit (REFIT_ITERATIONS)
#: per training point, the leading effect fitted again with the calibration (naming.Namer.refit):
#: its start, then per iteration the six factors' and the magnitude's sensitivities and the step
#: lengths tried, then its shape parameters
DIAGNOSIS_REFIT_RUNS = (1 + DIAGNOSIS_REFIT_ITERATIONS * (DIAGNOSIS_FACTORS + 1 + DIAGNOSIS_STEP_TRIALS)
                        + DIAGNOSIS_SHAPE_RUNS)
DIAGNOSIS_DETECT_RUNS = 3  # magnitudes per candidate for its detectability (weak, typical, strong)
DIAGNOSIS_DESIGN_RUNS = 5 * 3 * 5  # next-test design: candidate points x models (design.DESIGN_*)
DIAGNOSIS_DESIGN_S = 0.6 + 1.0  # simulated length of one design run [s] (start-up + design.DESIGN_RECORD)
#: simulated before each torsional record of a diagnosis run [s]: the measured drive's start-up
#: (MeasuredTorque's mean and amplitude ramps, 0.3 s each) and drive.DRIVE_SETTLE, 0.5 s
DIAGNOSIS_LEAD_IN_S = 0.6 + 0.5
#: replays of each ramp: as given, calibrated, its coarse check, six calibration sensitivities, each
#: fitted model (shortlist and a pair) with its magnitude sensitivities (two for the pair), the
#: sizing search of the most probable effect (10, and 3 for its curvature when the search ends
#: at a bound of its range, 2 otherwise) and that model afterwards
DIAGNOSIS_RAMP_SIZING = 10 + 3
#: ... and the detectability of the effects that show in ramps (three, design.RAMP_PROTOCOLS) at
#: three magnitudes each
DIAGNOSIS_RAMP_DETECT = 3 * 3
DIAGNOSIS_RAMP_RUNS = (3 + DIAGNOSIS_FACTORS + 2 * (DIAGNOSIS_SHORTLIST + 1) + 1 + DIAGNOSIS_RAMP_SIZING + 1
                       + DIAGNOSIS_RAMP_DETECT)


def diagnosis_runs(n_points: int, n_candidates: int, n_ramps: int = 0) -> int:
    """Upper bound of the model runs one diagnosis makes with ``n_points`` torsional points
    (every third held out) and ``n_candidates`` effects: compare (ten times: the model, its
    coarse discretisation, its input moved up and down by the input channel's uncertainty
    and the set moved up and down along the three directions the calibration cannot
    follow), coarse scan and Gauss-Newton (each iteration with up to two sensitivity steps)
    on the training points, the
    held-out check, the compare step's checks again at the calibrated set with one more
    Gauss-Newton step and its held-out check, a screen per candidate from two starts (the short
    springs' at DIAGNOSIS_SCREEN_EXTRA more shapes, counted whether or not they are among the
    candidates), the shortlist's fits from
    both starts (with their shape parameters; the short springs' count chosen first by
    DIAGNOSIS_CHOICE_RUNS runs) and their held-out checks, "no missing
    effect" at the calibration factors of each fitted effect (and its held-out check), the
    leading effect fitted again with the calibration (and its held-out check), a pair of
    effects (its partner screened among the other candidates on top of the leading fit, the
    short springs' clearances and the absorber's tuning orders DIAGNOSIS_PARTNER_EXTRA more
    runs, the short springs' count chosen there), the
    detectability runs of every candidate, and DIAGNOSIS_RAMP_RUNS per ramp. The
    next-test design's runs have their own length (:func:`diagnosis_cost`)."""
    n = max(0, int(n_points))
    held = n // 3 + (1 if n % 3 >= 2 else 0)
    train = n - held
    runs = DIAGNOSIS_COMPARE_RUNS * n
    runs += DIAGNOSIS_FACTORS * DIAGNOSIS_SCAN * train
    runs += DIAGNOSIS_ITERATIONS * DIAGNOSIS_DERIVATIVE_STEPS * (DIAGNOSIS_FACTORS + DIAGNOSIS_STEP_TRIALS) * train
    runs += held
    # the checks again at the calibrated set, one Gauss-Newton step under them and its held-out check
    runs += DIAGNOSIS_RECHECK_RUNS * n + DIAGNOSIS_STEP_TRIALS * train + held
    runs += DIAGNOSIS_STARTS * (int(n_candidates) + (DIAGNOSIS_SCREEN_EXTRA if n_candidates else 0)) * train
    shortlist = min(DIAGNOSIS_SHORTLIST, max(1, int(n_candidates)))
    runs += shortlist * (DIAGNOSIS_STARTS * DIAGNOSIS_FIT_RUNS * train + DIAGNOSIS_SHAPE_RUNS * train + held)
    runs += DIAGNOSIS_CHOICE_RUNS * train if n_candidates else 0
    runs += shortlist * train + held  # "none" at the factors of each fitted effect, its held-out check
    runs += DIAGNOSIS_REFIT_RUNS * train + held  # the leading effect re-calibrated, its held-out check
    runs += DIAGNOSIS_PAIR_RUNS * train + held
    if n_candidates >= 2:
        runs += (int(n_candidates) - 1 + DIAGNOSIS_PARTNER_EXTRA + DIAGNOSIS_CHOICE_RUNS) * train
    runs += DIAGNOSIS_DETECT_RUNS * int(n_candidates) * train
    runs += (DIAGNOSIS_RAMP_RUNS * max(0, int(n_ramps)) + n) if n_ramps else 0  # + the re-run after sizing
    return int(runs)


def diagnosis_cost(system, n_points: int, duration: float, n_candidates: int, n_ramps: int = 0,
                   ramp_duration: float = 0.0, workers: int = 2) -> Cost:
    """A diagnosis (:mod:`dampersim.discrepancy`): :func:`diagnosis_runs` runs of
    ``duration`` [s] (the longest torsional record) after DIAGNOSIS_LEAD_IN_S of start-up
    and settling, the next-test design's
    DIAGNOSIS_DESIGN_RUNS runs of DIAGNOSIS_DESIGN_S, plus DIAGNOSIS_RAMP_RUNS runs per ramp of
    ``ramp_duration`` [s]; bytes of ``workers`` runs in flight (the diagnosis runner's
    default is two processes)."""
    runs = diagnosis_runs(n_points, n_candidates, 0) + (max(0, int(n_points)) if n_ramps else 0)
    one = point_cost(system, DIAGNOSIS_LEAD_IN_S + duration, record_segments=False)
    design = point_cost(system, DIAGNOSIS_DESIGN_S, record_segments=False)
    work = runs * one.work + DIAGNOSIS_DESIGN_RUNS * design.work
    runs += DIAGNOSIS_DESIGN_RUNS
    peak = max(one.bytes, design.bytes)
    if n_ramps and ramp_duration > 0:
        ramp = point_cost(system, ramp_duration, record_segments=False)
        work += DIAGNOSIS_RAMP_RUNS * int(n_ramps) * ramp.work
        peak = max(peak, ramp.bytes)
    return Cost(float(work), float(max(1, int(workers)) * peak),
                f"a diagnosis of {int(n_points)} test points ({runs + DIAGNOSIS_RAMP_RUNS * max(0, int(n_ramps))} model runs)")


def _cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


# --------------------------------------------------------------------------- budgets
@dataclass(frozen=True)
class Budgets:
    """The server's budgets: ``limit`` and ``autostart`` [step·DOF], ``bytes_limit`` [B]."""

    limit: float = DEFAULT_LIMIT
    autostart: float = DEFAULT_AUTOSTART
    bytes_limit: float = DEFAULT_BYTES_LIMIT


def _env_number(name: str, default: float, unit: str, example: str) -> float:
    raw = os.environ.get(name)
    if raw is None or not raw.strip():
        return float(default)
    try:
        value = float(raw.strip())
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        shown = raw if len(raw) <= 40 else raw[:40] + "…"
        raise InputError(f"{name} = {shown!r}: accepted is a positive number of {unit}, e.g. {example}")
    return value


def budgets() -> Budgets:
    """The budgets from the environment, read now: ``DAMPERSIM_BUDGET`` and
    ``DAMPERSIM_AUTOSTART_BUDGET`` [step·DOF], ``DAMPERSIM_MEMORY_BUDGET`` [B]; unset
    ones take the defaults. An autostart budget above the limit is lowered to the limit.
    Raises InputError naming the variable, its value and what is accepted."""
    def example(work):
        return f"{work:.1e} (about {work_duration(work)} of one core)"

    limit = _env_number(BUDGET_ENV, DEFAULT_LIMIT, "step·DOF", example(DEFAULT_LIMIT))
    auto = _env_number(AUTOSTART_ENV, DEFAULT_AUTOSTART, "step·DOF", example(DEFAULT_AUTOSTART))
    mem = _env_number(BYTES_ENV, DEFAULT_BYTES_LIMIT, "bytes", f"{int(DEFAULT_BYTES_LIMIT)} (1 GiB)")
    return Budgets(limit=limit, autostart=min(auto, limit), bytes_limit=mem)


class BudgetError(InputError):
    """A request above the server's budget; the message gives the estimate and the limit."""

    def __init__(self, cost: Cost, budget: Budgets, foreground: bool = False):
        self.cost = cost
        self.budget = budget
        self.foreground = bool(foreground)
        over = []
        if cost.work > budget.limit:
            over.append(f"{_work_text(budget.limit)} step·DOF (about {work_duration(budget.limit)} of one core, "
                        f"{BUDGET_ENV})")
        elif foreground and cost.work > FOREGROUND_WORK:
            over.append(f"{_work_text(FOREGROUND_WORK)} step·DOF (about {work_duration(FOREGROUND_WORK)} "
                        "of one core) in a page that computes while you wait; run it with `dampersim simulate` "
                        "on the command line")
        if cost.bytes > budget.bytes_limit:
            over.append(f"{bytes_text(budget.bytes_limit)} of memory ({BYTES_ENV})")
        super().__init__(f"{cost.what} is {cost.text()} (about {cost.duration()} of one core); "
                         f"this server accepts at most {' and '.join(over)}")

    def __reduce__(self):
        return (type(self), (self.cost, self.budget, self.foreground))


def admit(cost: Cost, budget: Budgets | None = None, *, foreground: bool = False) -> str:
    """``"run"`` when ``cost`` is within the autostart budget, ``"ask"`` when it is within
    the limit but above the autostart budget (start only on an explicit Run). Raises
    :class:`BudgetError` above the work limit or the memory limit, and, for a request
    computed in the request thread (``foreground``), above :data:`FOREGROUND_WORK`."""
    budget = budget if budget is not None else budgets()
    limit = min(budget.limit, FOREGROUND_WORK) if foreground else budget.limit
    if not (cost.work <= limit and cost.bytes <= budget.bytes_limit):  # NaN is refused too
        raise BudgetError(cost, budget, foreground)
    return "ask" if cost.work > budget.autostart else "run"


# --------------------------------------------------------------------------- foreground slots
class ServerBusy(InputError):
    """Every foreground slot is taken: nothing was computed, the page keeps its results."""

    def __init__(self, slots: int):
        self.slots = int(slots)
        super().__init__(f"the server is busy with {self.slots} other interactive computation"
                         f"{'s' if self.slots != 1 else ''}; try again in a moment (at most {self.slots} run at once: "
                         f"{FOREGROUND_SLOTS_ENV})")

    def __reduce__(self):
        return (type(self), (self.slots,))


_SLOTS_LOCK = threading.Lock()
_SEMAPHORES: dict = {}


def foreground_slots() -> int:
    """Foreground computations allowed at once (``DAMPERSIM_FOREGROUND_SLOTS``, read now;
    default :data:`DEFAULT_FOREGROUND_SLOTS`). Raises InputError naming the variable, its
    value and what is accepted."""
    raw = os.environ.get(FOREGROUND_SLOTS_ENV)
    if raw is None or not raw.strip():
        return DEFAULT_FOREGROUND_SLOTS
    try:
        value = int(raw.strip())
    except ValueError:
        value = 0
    if value < 1:
        shown = raw if len(raw) <= 40 else raw[:40] + "…"
        raise InputError(f"{FOREGROUND_SLOTS_ENV} = {shown!r}: accepted is a whole number of at least 1, "
                         f"e.g. {DEFAULT_FOREGROUND_SLOTS} (half the server's request threads)")
    return value


@contextmanager
def foreground_slot():
    """Hold one of the :func:`foreground_slots` of this process while a page computes in
    its request thread. Never waits: when every slot is taken it raises :class:`ServerBusy`
    at once, before anything is computed (a waiting request would hold its thread all the
    same). Wrap only the computation, not a cache hit."""
    slots = foreground_slots()
    with _SLOTS_LOCK:
        sem = _SEMAPHORES.setdefault(slots, threading.BoundedSemaphore(slots))
    if not sem.acquire(blocking=False):
        raise ServerBusy(slots)
    try:
        yield
    finally:
        sem.release()


__all__ = [
    "STEP_DOF_PER_SECOND",
    "FOREGROUND_WORK",
    "DEFAULT_FOREGROUND_SLOTS",
    "FOREGROUND_SLOTS_ENV",
    "ServerBusy",
    "foreground_slots",
    "foreground_slot",
    "DEFAULT_AUTOSTART",
    "DEFAULT_LIMIT",
    "DEFAULT_BYTES_LIMIT",
    "BUDGET_ENV",
    "AUTOSTART_ENV",
    "BYTES_ENV",
    "Cost",
    "bytes_text",
    "duration_text",
    "work_duration",
    "degrees_of_freedom",
    "segment_nodes",
    "run_bytes",
    "point_cost",
    "sweep_cost",
    "ramp_cost",
    "GENERATOR_DOF_WEIGHT",
    "pulsation_cost",
    "diagnosis_runs",
    "diagnosis_cost",
    "Budgets",
    "budgets",
    "BudgetError",
    "admit",
]
