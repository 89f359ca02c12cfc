"""A benchmark run with the naming's fits traced: what each fitted model leaves at each training
point, what the linear screen promised against what the fit reached, and the leading effect's
re-calibration from other shapes.

Runs ``bench/bench_discrepancy.py`` in this process with the arguments after ``--`` and writes
one JSON line per event to ``--trace``:

* ``screen``: a shortlisted candidate's screen evidence [nats], the screen's linearised
  objective at its best scale and shape (least squares at the calibrated model's stored point
  weights, not the fits' robust loss: compare it with the same form of "none"), that scale
  (of the typical magnitude), its start, and the objectives of the fits made from it;
* ``evidence``: each time a model's evidence is read (several times for "none" and for a
  model refitted or tempered): its effects, its fit's start, learning rate, log evidence,
  objective (robust loss plus priors), magnitude, and the reduced chi^2 of each training
  point (unweighted, at the model's own channel nuisance);
* ``refit`` (only when the re-calibration runs, docs/discrepancy.md, Naming 3b): the first
  fit and the re-calibration before its shape step (objective, magnitude, log factors,
  shapes); with ``--refit-shapes`` also side re-calibrations from those shapes, each before
  and after its shape step. The side runs do not enter the diagnosis (their failed runs are
  not recorded against the effect, and an error in one is written to the event), but they
  are model runs: the case's run count and wall time include them;
* ``shape_step``: every shape step (the first fits' and the re-calibration's): objective
  before, and the fit after;
* with ``--fresh-columns``, the ``evidence`` event of a single effect whose shape step moved
  it also carries ``fresh_columns``: its log evidence and Laplace intervals (90 %, before the
  jackknife) as the diagnosis reads them, with the shape parameters' columns from where the
  fit started its shape step and the magnitude's from its fit (Namer.fit's, or the
  re-calibration's last iteration), and again with these columns taken afresh at the fit's
  final point (1 + shapes runs per training point, once per fit). The calibration factors'
  columns are not refreshed;
* ``side_fit`` (with ``--side-fits``): after an effect's first fit has taken its shape step,
  the same fit (magnitude, re-calibration and shape step, from the same start) made again from
  each given shape instead of the screen's (a discrete shape such as the short springs' count
  is the set's unless given): the fit before and after its shape step. It asks
  whether another basin of the shape parameters fits the training points better than the one
  the fit reached. Like the side refits, these fits do not enter the diagnosis but their runs
  count in the case's run count and wall time.

The wrapping replaces methods of ``dampersim.discrepancy.naming.Namer`` while the benchmark
runs. The figures of docs/discrepancy.md, "Re-calibrating the screen's leader", were read
with two ad hoc wrappers of the same methods that this script joins (one for the
re-calibration and shape steps, one for the screen and the evidence), against the library of
commit 4dad05a, where the re-calibration went to the short springs. On later commits it
goes to the leader by fitted evidence; side refits run only for the effect it goes to, and
the script warns about a given effect that was never re-calibrated:

    python bench/bench_fit_trace.py --trace t.jsonl \\
        --refit-shapes '{"inner_short_springs": {"screen": {"clearance": 0.05, "count": 3}}}' -- \\
        --only effect/inner_short_springs/typical/s0 --out r.jsonl --no-recommend --workers 1

The absorber's fits from other tunings (docs/discrepancy.md, "The typical absorber from other
tunings"; "The intervals with the derivatives taken after the shape step" adds
``--fresh-columns`` instead of ``--side-fits``):

    python bench/bench_fit_trace.py --trace t.jsonl --side-fits '{"pendulum_absorber": {"low": {"order": 1.92},
        "low_damped": {"order": 1.92, "damping": 0.05}, "truth": {"order": 1.945, "damping": 0.0742}}}' -- \\
        --only effect/pendulum_absorber/typical/s0 --out r.jsonl --no-recommend --workers 1

(the line break inside the quotes is white space in JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import runpy
import sys

import numpy as np

from dampersim.discrepancy import naming
from dampersim.discrepancy.effects import info, with_effect
from dampersim.discrepancy.selection import interval90
from dampersim.errors import InputError, ParameterError
from dampersim.parameters import default_parameters

HERE = os.path.dirname(os.path.abspath(__file__))
WRAPPED = ("fit_candidate", "evidence", "refit", "fit_shapes")


def install(write, refit_shapes: dict, side_fits: dict | None = None, fresh_columns: bool = False) -> dict:
    """Wrap Namer's screen-to-fit, evidence, re-calibration and shape steps so that each writes
    its event through ``write`` (a callable taking a dict); ``refit_shapes`` and ``side_fits``
    ({effect: {label: shape values}}, :func:`checked_shapes`) name the side re-calibrations and
    the side fits; ``fresh_columns`` adds the evidence read with columns at the fit's final
    point. Returns the plain methods ({name: function}) for :func:`uninstall`."""
    Namer = naming.Namer
    plain = {attr: getattr(Namer, attr) for attr in WRAPPED}
    refreshed = {}  # (fit id, magnitude, shapes) -> (the fit, its columns at its final point, zeroed)

    def state(self, name, fit) -> dict | None:
        if fit is None:
            return None
        return {"cost": float(fit["cost"]), "m": float(fit["m"]), "x": [float(v) for v in fit["x"]],
                "shape": {k: float(v) for k, v in self.shape_values(name, fit["system"]).items()}}

    def fit_candidate(self, name, screened):
        fits = plain["fit_candidate"](self, name, screened)
        write({"event": "screen", "name": name, "rel_log_evidence": float(screened["rel_log_evidence"]),
               "screen_cost": float(screened["cost"]), "scale": float(screened["scale"]),
               "start": screened["start"], "shape": {k: float(v) for k, v in (screened.get("shape") or {}).items()},
               "fit_costs": [float(f["cost"]) for f in fits]})
        return fits

    def evidence(self, fit, names, bias=None, eta: float = 1.0):
        out = plain["evidence"](self, fit, names, bias, eta)
        chi2 = self.lik.point_chi2(fit["y"], self.train, fit.get("nuisance")) / (2 * len(self.lik.orders))
        event = {"event": "evidence", "effects": list(names), "start": fit.get("start"), "eta": float(eta),
                 "log_evidence": float(out[0]), "cost": float(fit["cost"]), "m": float(fit.get("m") or 0.0),
                 "point_reduced_chi2": {p.id: float(c) for p, c in zip(self.points, chi2)}}
        if fresh_columns and len(names) == 1 and fit.get("shapes") and fit.get("base") is None:
            event["fresh_columns"] = read_fresh(self, names[0], fit, out, bias, eta)
        write(event)
        return out

    def columns_at(self, name, fit) -> tuple:
        """(columns, zeroed): the magnitude's and the stepped shapes' standardised columns at the
        fit's final point, formed by the library's Namer.magnitude_column and Namer.shape_columns
        (a column whose run fails, or whose shape sits at its bound, is zero), and the parameters
        whose column is zero."""
        held, zeroed = self.shape_values(name, fit["system"]), []
        cols = [self.magnitude_column(name, fit, zeroed=zeroed),
                *self.shape_columns(name, fit, {q: float(held[q]) for q in fit["shape_start"]}, zeroed)]
        return cols, zeroed

    def read_fresh(self, name, fit, out, bias, eta) -> dict:
        as_run = {"log_evidence_as_run": float(out[0]),
                  "column_norms_as_run": [float(np.linalg.norm(c)) for c in fit["columns"]]}
        key = (id(fit), float(fit["m"]), tuple(sorted(fit["shapes"].items())))
        kept = dict(self.failures.get(name, {}))
        try:
            if key not in refreshed or refreshed[key][0] is not fit:  # the fit is held: its id is not reused
                refreshed[key] = fit, *columns_at(self, name, fit)
            _, cols, zeroed = refreshed[key]
            alt = plain["evidence"](self, dict(fit, columns=cols), [name], bias, eta)
        except Exception as exc:  # the read must not end the diagnosis: its error goes to the event
            return {**as_run, "error": f"{type(exc).__name__}: {exc}"}
        finally:
            self.failures[name] = kept  # these runs' failed points are not the effect's
        held = self.shape_values(name, fit["system"])
        values = {info(name).magnitude: float(fit["m"]), **{q: float(held[q]) for q in fit["shape_start"]}}
        n = self.jac.shape[1]

        def laplace(cov):  # value, 90 % low and high, standard deviation in log
            sd = np.sqrt(np.maximum(np.diag(cov)[n:n + len(values)], 0.0))
            return {q: [v, *interval90(math.log(v), float(s)), float(s)] for (q, v), s in zip(values.items(), sd)}

        return {**as_run, "log_evidence": float(alt[0]), "laplace_as_run": laplace(out[1]), "laplace": laplace(alt[1]),
                "column_norms": [float(np.linalg.norm(c)) for c in cols], "zeroed": zeroed}

    def refit(self, name, fit):
        out = plain["refit"](self, name, fit)
        event = {"event": "refit", "name": name, "first_fit": state(self, name, fit), "refit": state(self, name, out),
                 "side": []}
        kept = dict(self.failures.get(name, {}))
        for label, shape in refit_shapes.get(name, {}).items():
            entry = {"from": label, "shape": shape}
            try:
                side = plain["refit"](self, name, dict(fit, system=with_effect(fit["system"], name, shape)))
                entry["refit"] = state(self, name, side)
                entry["after_shape_step"] = state(self, name, plain["fit_shapes"](self, name, side)) if side else None
            except Exception as exc:  # a side run must not end the diagnosis: its error goes to the event
                entry["error"] = f"{type(exc).__name__}: {exc}"
            event["side"].append(entry)
        self.failures[name] = kept  # the side runs' failed points are not the effect's
        write(event)
        return out

    def fit_shapes(self, name, fit):
        before = None if fit is None else float(fit["cost"])
        out = plain["fit_shapes"](self, name, fit)
        write({"event": "shape_step", "name": name, "cost_before": before, "fit": state(self, name, out)})
        if out is not None and out.get("base") is None and out.get("start") in self.starts:  # a first fit
            side_fit(self, name, out["start"])
        return out

    def side_fit(self, name, start):
        given = (side_fits or {}).get(name)
        if not given:
            return
        kept = dict(self.failures.get(name, {}))
        for label, shape in given.items():
            event = {"event": "side_fit", "name": name, "from": label, "shape": shape, "start": start}
            try:
                side = self.fit(name, start, shape=shape)
                event["fit"] = state(self, name, side)
                event["after_shape_step"] = state(self, name, plain["fit_shapes"](self, name, side)) if side else None
            except Exception as exc:  # a side fit must not end the diagnosis: its error goes to the event
                event["error"] = f"{type(exc).__name__}: {exc}"
            write(event)
        self.failures[name] = kept  # the side fits' failed points are not the effect's

    for attr, wrapped in zip(WRAPPED, (fit_candidate, evidence, refit, fit_shapes)):
        setattr(Namer, attr, wrapped)
    return plain


def uninstall(plain: dict) -> None:
    """Put back the methods :func:`install` replaced."""
    for attr, method in plain.items():
        setattr(naming.Namer, attr, method)


def checked_shapes(text: str, option: str = "--refit-shapes") -> dict:
    """{effect: {label: {shape values}}} from ``option`` (one set of values per effect, or
    several labelled ones), each checked against the default parameter set before any run;
    raises ValueError with what is accepted."""
    accepted = ('accepted is an object of effect name -> shape values, or -> labels -> shape values, e.g. '
                '{"inner_short_springs": {"clearance": 0.064, "count": 3}}')
    try:
        given = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"{option}: not JSON ({exc}); {accepted}") from None
    if not isinstance(given, dict) or not all(isinstance(v, dict) for v in given.values()):
        raise ValueError(f"{option}: {accepted}")
    out = {}
    for name, values in given.items():
        try:
            info(name)
        except InputError:
            raise ValueError(f"{option}: {name!r} is not an effect of the library; {accepted}") from None
        sets = values if values and all(isinstance(v, dict) for v in values.values()) else {"given": values}
        for label, shape in sets.items():
            try:
                with_effect(default_parameters(), name, shape)
            except (ParameterError, TypeError, ValueError, AttributeError) as exc:
                raise ValueError(f"{option}: {name} {label}: {exc}") from None
        out[name] = sets
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trace", required=True, help="JSON lines file the events are appended to")
    ap.add_argument("--refit-shapes", default="{}",
                    help='side re-calibrations: {effect: {shape values}} or {effect: {label: {shape values}}}')
    ap.add_argument("--side-fits", default="{}",
                    help="side fits after an effect's first shape step, from these shapes (same form)")
    ap.add_argument("--fresh-columns", action="store_true",
                    help="read a shape-stepped single effect's evidence also with columns at its final point")
    ap.add_argument("bench_args", nargs=argparse.REMAINDER, help="-- then bench_discrepancy.py's arguments")
    args = ap.parse_args(argv)
    try:
        shapes = checked_shapes(args.refit_shapes)
        sides = checked_shapes(args.side_fits, "--side-fits")
    except ValueError as exc:
        ap.error(str(exc))
    rest = args.bench_args[1:] if args.bench_args[:1] == ["--"] else args.bench_args
    if not rest:
        ap.error("no benchmark arguments: give them after --, e.g. -- --only control/none/1 --out r.jsonl "
                 "(without any, bench_discrepancy.py would run its whole matrix)")
    argv0 = sys.argv
    with open(args.trace, "a", encoding="utf-8") as fh:
        refitted = set()  # the effects re-calibrated: a given side shape of any other never ran
        side_fitted = set()  # the effects with a first fit: a given side fit of any other never ran

        def write(event):
            if event["event"] == "refit":
                refitted.add(event["name"])
            if event["event"] == "side_fit":
                side_fitted.add(event["name"])
            fh.write(json.dumps(event) + "\n")
            fh.flush()

        plain = install(write, shapes, sides, args.fresh_columns)
        sys.argv = [os.path.join(HERE, "bench_discrepancy.py"), *rest]
        code = 0
        try:
            runpy.run_path(sys.argv[0], run_name="__main__")
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        finally:
            uninstall(plain)
            sys.argv = argv0
    for name in sorted(set(shapes) - refitted):
        print(f"note: {name} was never re-calibrated (Naming 3b chose another effect, or no fit needed it): "
              "its --refit-shapes did not run", file=sys.stderr)
    for name in sorted(set(sides) - side_fitted):
        print(f"note: {name} had no first fit (not shortlisted, every fit failed, or no naming ran): "
              "its --side-fits did not run", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
