"""The next test to run: candidate rig points ranked by how well they would separate the
most probable models, or reveal an effect this campaign cannot see.

Every candidate torsional point (a speed x mean torque grid spanning and extending the
campaign's, driven by a 2nd-order fluctuation like the campaign's dominant input order) is
simulated with each model in question: the calibrated damper ("none") and the fitted
effect models, or an effect at its typical magnitude when the campaign cannot detect it.
A candidate scores the chi^2 distance between two models' output orders there, in units of
the campaign's own per-order uncertainty (its median over points): the expected chi^2 the
measurement would add for telling them apart. Effects that show mainly in slow ramps
(free play, a third stiffness stage, clutch creep) also get a ramp protocol of
``hysteresis --protocol``.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy.effects import info, with_effect
from dampersim.excitation import OrderSum, parse_orders
from dampersim.simulation import simulate
from dampersim.units import rpm_to_rad_s

#: mean torques of the candidate grid [N m]: below, at and above the knee of the default
#: damper (about 300 N m), like the accuracy grid of docs/model.md §12
DESIGN_TORQUES = (100.0, 300.0, 450.0)
#: candidate speeds [rpm]: the rig's range in [thesis] §3
DESIGN_SPEEDS = (1000.0, 1500.0, 2000.0, 2500.0, 3000.0)
#: analysed record of a candidate run after the 0.6 s start-up [s]
DESIGN_RECORD = 1.0
#: recommendations returned
DESIGN_KEEP = 5
#: ramp protocol that shows each ramp-visible effect best ([thesis] Table 3.1): free play at
#: the zero crossings of a small symmetric ramp, the third stage and clutch creep at a high
#: held torque
RAMP_PROTOCOLS = {"output_backlash": "full-100", "inner_short_springs": "full-450", "clutch_slip": "pos-350-450"}
#: orders compared (those of the diagnosis)
ORDERS = tuple(float(k) for k in range(1, 9))


def design_task(args) -> dict:
    """Output order amplitudes [N m] of one candidate: args = (system, speed [rad/s], mean
    torque [N m], orders text); {"error": text} when the run fails."""
    system, speed, torque, text = args
    try:
        ex = OrderSum(speed, torque, parse_orders(text))
        res = simulate(system, ex, duration=ex.steady_start + DESIGN_RECORD, record_segments=False)
        a = res.order_amplitudes(ORDERS, seconds=DESIGN_RECORD)[1]
    except Exception as exc:  # noqa: BLE001 - a failed candidate is skipped, not fatal
        return {"error": f"{type(exc).__name__}: {exc}"}
    if not np.all(np.isfinite(a)):
        return {"error": "non-finite order amplitudes"}
    return {"orders": np.asarray(a, dtype=float)}


def candidates(points, fluctuation_nm: float) -> list:
    """(speed [rpm], mean torque [N m], orders text) of every candidate point: the design
    grid (speeds within 20 % beyond the campaign's range) with the campaign's dominant input
    amplitude on the 2nd order."""
    speeds = [p.speed_rpm for p in points]
    lo, hi = 0.8 * min(speeds), 1.2 * max(speeds)
    text = f"2:{max(10.0, round(fluctuation_nm)):g}"
    grid = [s for s in DESIGN_SPEEDS if lo <= s <= hi] or [float(round(np.median(speeds), -2))]
    return [(s, t, text) for s in grid for t in DESIGN_TORQUES]


def _score(a, b, sigma) -> tuple:
    """(chi^2 distance, order index of its largest share) of two amplitude rows."""
    d = ((np.asarray(a) - np.asarray(b)) / sigma) ** 2
    return float(np.sum(d)), int(np.argmax(d))


def recommend(runner, models: dict, contrasts: list, points, sigma_by_order, fluctuation_nm: float,
              ramps_present: bool, hidden: list) -> list:
    """Ranked next test points.

    models: {label: parameter set}; contrasts: [(label a, label b, why)] pairs of models to
    separate; sigma_by_order: the campaign's per-order uncertainty [N m]; hidden: effects
    the campaign cannot detect (their ramp protocols are proposed too). Returns the
    ``recommended_points`` entries (kind, speed_rpm, mean_torque_nm, orders, protocol,
    reason), best first."""
    from dampersim.discrepancy.drive import diagnosis_system

    cands = candidates(points, fluctuation_nm)
    labels = sorted({x for a, b, _ in contrasts for x in (a, b)})
    tasks = [(diagnosis_system(models[lab]), rpm_to_rad_s(s), t, text) for lab in labels for s, t, text in cands]
    out = runner.map(tasks, fn=design_task) if tasks else []
    amps = {(labels[i // len(cands)], cands[i % len(cands)][0], cands[i % len(cands)][1]): r.get("orders")
            for i, r in enumerate(out)}
    sigma = np.maximum(np.asarray(sigma_by_order, dtype=float), 1e-9)
    rows = []
    for a, b, why in contrasts:
        best = None
        for s, t, text in cands:
            ya, yb = amps.get((a, s, t)), amps.get((b, s, t))
            if ya is None or yb is None:
                continue
            score, k = _score(ya, yb, sigma)
            if best is None or score > best[0]:
                best = (score, s, t, text, k, ya[k], yb[k])
        if best is None:
            continue
        score, s, t, text, k, va, vb = best
        rows.append({"kind": "torsional", "speed_rpm": float(s), "mean_torque_nm": float(t), "orders": text,
                     "protocol": None, "score": score,
                     "reason": (f"{why}: {a} and {b} differ here by chi^2 = {score:.3g} (order {k + 1}: "
                                f"{va:.3g} against {vb:.3g} N m, uncertainty {sigma[k]:.2g} N m)")})
    rows.sort(key=lambda r: -r["score"])
    seen, kept = set(), []
    for r in rows:  # one recommendation per point
        key = (r["speed_rpm"], r["mean_torque_nm"])
        if key not in seen:
            seen.add(key)
            kept.append(r)
    ramp_for = [e for e in dict.fromkeys([*labels, *hidden]) if e in RAMP_PROTOCOLS]
    speed = float(min(p.speed_rpm for p in points))
    for e in ramp_for:
        kept.append({"kind": "ramp", "speed_rpm": speed, "mean_torque_nm": 0.0, "orders": None,
                     "protocol": RAMP_PROTOCOLS[e], "score": math.nan,
                     "reason": (f"{e} shows in slow ramps ({info(e).signature.split(';')[0]})"
                                + ("" if ramps_present else "; the campaign has no ramp"))})
    for r in kept:
        r.pop("score")
    return kept[:DESIGN_KEEP + len(ramp_for)]


def effect_model(system, name: str):
    """``system`` with effect ``name`` at its typical magnitude (a model to look for)."""
    e = info(name)
    return with_effect(system, name, {e.magnitude: e.magnitudes[1]})


__all__ = ["DESIGN_TORQUES", "DESIGN_SPEEDS", "DESIGN_RECORD", "RAMP_PROTOCOLS", "design_task", "candidates",
           "recommend", "effect_model"]
