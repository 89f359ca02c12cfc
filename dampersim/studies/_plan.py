"""Plans of the chapter 7 studies: every simulation a study will make, listed before any is made.

A study first builds its :class:`Plan` from its grid (test points for the cached MR
sweeps, ``(system, excitation, duration)`` jobs for the cached single runs) and then
executes exactly that plan (:func:`execute`). The same plan, built without running it,
gives the study's cost (:func:`plan_cost`) in step·DOF [-] and bytes [B] through
:mod:`dampersim.costs`, so an estimate follows the study's grid whenever the grid changes.

No study is adaptive: every sweep's points and every run's inputs follow from the grid
alone, never from an earlier result, so the plan is the study's run list, not a bound of
it. The cost counts every run as computed (a cache hit is not looked up: that needs the
kernel's source hash and a disk look-up per point), an upper bound when some are cached.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dampersim import costs
from dampersim.results import ANALYSIS_WINDOW
from dampersim.studies._common import Progress, cached_runs, mr_sweep
from dampersim.sweeps.backends import cpu_count
from dampersim.sweeps.cache import resolved_duration


@dataclass(frozen=True)
class SweepStep:
    """One MR sweep (:func:`dampersim.studies._common.mr_sweep`): ``system`` and its test
    ``points`` (speed [rad/s], mean torque [N m], orders), each simulated for its natural
    duration [s] (the solver's ``duration`` for a steady test point) without a segment record."""

    system: object
    points: tuple

    @property
    def units(self) -> int:
        """Progress units [-]: the sweep reports every test point, repeated ones too."""
        return len(self.points)

    def distinct_points(self) -> tuple:
        """The points the sweep simulates: :func:`~dampersim.sweeps.executor.run_sweep`
        computes a repeated point once. Equal :class:`~dampersim.sweeps.TestPoint` values
        (normalised floats) give equal excitations and so equal cache keys, different
        values different ones, so equality of the points is the sweep's own test."""
        return tuple(dict.fromkeys(self.points))

    def simulations(self) -> int:
        """Simulations [-] the sweep makes on an empty cache."""
        return len(self.distinct_points())

    def cost(self) -> costs.Cost:
        """Work [step·DOF]: each distinct point at its own duration. Bytes [B]: the sweep's
        points in flight and their stored spectra (:func:`dampersim.costs.sweep_cost`) at
        the longest duration, an upper bound when durations differ."""
        pts = self.distinct_points()
        durations = [resolved_duration(self.system, p.excitation()) for p in pts]
        runs_of = {d: durations.count(d) for d in set(durations)}  # one estimate per distinct duration
        work = sum(n * costs.point_cost(self.system, d, record_segments=False).work for d, n in runs_of.items())
        peak = costs.sweep_cost(self.system, len(pts), max(durations), ANALYSIS_WINDOW).bytes if pts else 0.0
        return costs.Cost(float(work), float(peak))


@dataclass(frozen=True)
class RunsStep:
    """Cached single runs (:func:`dampersim.studies._common.cached_runs`): ``fn(system,
    excitation, duration)`` for each job of ``jobs``, under the study-cache ``tag``; each
    run simulates ``duration`` [s] with its segment record (``record_segments`` True, as
    :func:`dampersim.simulate` does by default)."""

    tag: str
    fn: object
    jobs: tuple
    record_segments: bool = True

    @property
    def units(self) -> int:
        """Progress units [-]: one per job."""
        return len(self.jobs)

    def simulations(self) -> int:
        """Simulations [-] on an empty cache: every job (repeated jobs are not merged)."""
        return len(self.jobs)

    def cost(self, workers: int | None = None) -> costs.Cost:
        """Work [step·DOF]: the sum over the jobs. Bytes [B]: ``workers`` runs in flight
        (default: all usable cores, the most :func:`~dampersim.studies._common.cached_runs`
        gives its pool: it shares them with the other running jobs, so it uses as many or
        fewer), each of the largest run."""
        if not self.jobs:
            return costs.Cost(0.0, 0.0)
        each = [costs.point_cost(s, d, record_segments=self.record_segments) for s, _ex, d in self.jobs]
        workers = max(1, min(len(each), int(workers or cpu_count())))
        return costs.Cost(float(sum(c.work for c in each)), float(workers * max(c.bytes for c in each)))


class Plan:
    """A study's steps (:class:`SweepStep`, :class:`RunsStep`, run in this order) and the
    grid values its analysis needs (as attributes, from ``context``)."""

    def __init__(self, steps, **context):
        self.steps = tuple(steps)
        self.__dict__.update(context)

    @property
    def total(self) -> int:
        """Progress units [-] of the whole study (test points and jobs)."""
        return sum(s.units for s in self.steps)

    def simulations(self) -> int:
        """Simulations [-] the study makes on an empty cache. A point repeated in two sweeps
        of one study would count twice (the cache serves the second): an upper bound."""
        return sum(s.simulations() for s in self.steps)


def plan_cost(plan: Plan, what: str) -> costs.Cost:
    """Cost of running ``plan`` with every result computed: work [step·DOF] summed over the
    steps; bytes [B] the largest step's, since the steps run one after another and each
    keeps only its small table or its JSON results once done."""
    parts = [s.cost() for s in plan.steps]
    work = sum(c.work for c in parts)
    peak = max((c.bytes for c in parts), default=0.0)
    if not (math.isfinite(work) and math.isfinite(peak)):
        work, peak = math.inf, math.inf
    return costs.Cost(float(work), float(peak), what)


def execute(plan: Plan, prog: Progress, executor: str, cancel=None) -> list:
    """Run ``plan``'s steps in order -> one output per step: a sweep's table, or the list
    of the runs' results."""
    out = []
    for step in plan.steps:
        if isinstance(step, SweepStep):
            out.append(mr_sweep(step.system, list(step.points), prog, executor, cancel))
        else:
            out.append(cached_runs(step.tag, step.fn, list(step.jobs), prog, parallel=(executor == "processes"),
                                   cancel=cancel))
    return out
