"""Sweeps over test points (speed x mean torque x excitation) with a result cache.

    from dampersim import default_parameters
    from dampersim.sweeps import make_grid, parse_range, run_sweep

    points = make_grid(parse_range("900:2800:10"), [200.0], "2:300,4:100")
    result = run_sweep(default_parameters(), points)   # all cores, cached on disk
    result.table                                         # one row per point and order

Modules: :mod:`~dampersim.sweeps.grid` (test points, ranges in rpm -> rad/s),
:mod:`~dampersim.sweeps.cache` (keys, stored records, diskcache store),
:mod:`~dampersim.sweeps.executor` (planning a sweep through the cache) and
:mod:`~dampersim.sweeps.backends` (serial, processes, Dask). The ``sweep`` and ``map``
commands are in :mod:`dampersim.cli.sweeps`.
"""

from dampersim.sweeps.grid import TestPoint, make_grid, parse_range, parse_torques, parse_values, speed_sweep
from dampersim.sweeps.cache import PointRecord, ResultCache, cache_dir, cache_key, kernel_source_hash

_EXECUTOR_NAMES = ("run_sweep", "SweepResult", "SweepCancelled", "SweepPointFailed")


def __getattr__(name):
    # the executor pulls in pandas; import it only when asked for
    if name in _EXECUTOR_NAMES:
        from dampersim.sweeps import executor

        return getattr(executor, name)
    raise AttributeError(f"module 'dampersim.sweeps' has no attribute {name!r}")


__all__ = [
    "TestPoint",
    "make_grid",
    "parse_range",
    "parse_torques",
    "parse_values",
    "speed_sweep",
    "PointRecord",
    "ResultCache",
    "cache_dir",
    "cache_key",
    "kernel_source_hash",
    *_EXECUTOR_NAMES,
]
