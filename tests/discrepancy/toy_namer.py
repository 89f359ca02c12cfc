"""A stand-in for the diagnosis's model runs in tests of the naming's Gauss-Newton steps: the
runs are patched to call a smooth toy function of the parameter set, so that the steps can be
checked against known answers without simulating."""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import drive
from dampersim.discrepancy.fitting import CALIBRATION
from dampersim.parameters import default_parameters

#: the parameter set the toys' log factors are read against (and the tests build their sets from)
BASE = default_parameters()


def log_factors(system) -> np.ndarray:
    """The six calibration groups' log factors of ``system`` against the default set (each read
    from its group's first member)."""
    flat = {"outer.spring.stiffness": (system.outer.spring.stiffness, BASE.outer.spring.stiffness),
            "inner.spring.stiffness": (system.inner.spring.stiffness, BASE.inner.spring.stiffness),
            "inertias.primary": (system.inertias.primary, BASE.inertias.primary),
            "inertias.secondary": (system.inertias.secondary, BASE.inertias.secondary),
            "friction.outer.alpha": (system.friction.outer.alpha, BASE.friction.outer.alpha),
            "friction.pair_outer.alpha": (system.friction.pair_outer.alpha, BASE.friction.pair_outer.alpha)}
    return np.array([math.log(flat[members[0]][0] / flat[members[0]][1]) for members in CALIBRATION.values()])


def patch_runs(monkeypatch, toy, fails, calls=None) -> None:
    """Make drive.coefficients_of_sets and drive.coefficients_of return ``toy(system)``'s rows
    (points x orders) for the points asked (ids "p0", "p1", ...); a system for which
    ``fails(runner, system)`` is true fails at every point (NaN rows and an error per point).
    ``calls``, if given, gets one entry per point run."""

    def coefficients_of_sets(runner, systems, points, errors=None, halves=None):
        out = np.array([[toy(s)[int(p.id[1:])] for p in points] for s in systems])
        for k, s in enumerate(systems):
            if calls is not None:
                calls.extend([1] * len(points))
            if fails(runner, s):
                out[k] = np.nan
                if errors is not None:
                    errors[k].update({i: "diverged" for i in range(len(points))})
        return out

    def coefficients_of(runner, system, points, errors=None):
        return coefficients_of_sets(runner, [system], points, None if errors is None else [errors])[0]

    monkeypatch.setattr(drive, "coefficients_of_sets", coefficients_of_sets)
    monkeypatch.setattr(drive, "coefficients_of", coefficients_of)
