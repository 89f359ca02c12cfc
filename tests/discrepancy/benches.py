"""Loading a benchmark script of bench/ as a module, for tests of its pure functions."""

import importlib.util
import pathlib

BENCH_DIR = pathlib.Path(__file__).resolve().parents[2] / "bench"


def load_bench(name: str):
    """The module of ``bench/<name>.py`` (run as an import: its ``main`` is not called)."""
    spec = importlib.util.spec_from_file_location(name, BENCH_DIR / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class NullRunner:
    """A stand-in for ``drive.Runner`` in bench tests: a context manager that runs nothing
    (a test subclasses it with the ``map`` it needs, or replaces the functions that use it)."""

    def __init__(self, workers=None):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
