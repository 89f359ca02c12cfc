"""A fired four-cylinder diesel as a torque source ([thesis] §4.3.2, §7.1.1).

Cylinder pressure from a single-zone model: polytropic compression from the inlet
pressure, a Wiebe heat release around TDC and polytropic expansion; the energy equation
dp/dtheta = (gamma - 1)/V dQ/dtheta - gamma p/V dV/dtheta is linear in (p, Q), so the
fuel energy that yields a requested mean torque follows exactly from two pressure
traces (motored and per joule of heat). Four cylinders fire every 180 deg (order
1-3-4-2) on a rigid crank; the flywheel torque is the gas torque plus the reciprocating
inertia torque minus ring and bearing friction. Its order content (2nd dominant, then 4th
and 6th, small half orders) is what the thesis's fired-engine signals show (§7.1.1:
2nd, 4th, 6th dominant at 100-550 N m, the next order below 50 N m).

:func:`fired_engine_excitation` gives an :class:`~dampersim.excitation.OrderSum` with the
engine's orders 0.5-8 (amplitudes and phases) at a speed and mean torque, e.g. along
the WOT curve (:func:`dampersim.excitation.torque_curve.default_torque_curve`).
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.errors import InputError
from dampersim.parameters.engine import FiredEngine
from dampersim.excitation.orders import OrderSum
from dampersim.excitation.torque_curve import default_torque_curve

N_CYCLE = 1440  # crank-angle samples per 720 deg cycle
ORDERS = tuple(0.5 * k for k in range(1, 17))


def _kinematics(geom, th):
    r, L = geom.crank_radius, geom.rod_length
    sn, cs = np.sin(th), np.cos(th)
    root = np.sqrt(L * L - r * r * sn * sn)
    s = r * (1 - cs) + L - root
    ds = r * sn + r * r * sn * cs / root
    dds = r * cs + r * r * (cs * cs - sn * sn) / root + (r * r * sn * cs) ** 2 / root**3
    return s, ds, dds


def _pressure_traces(eng: FiredEngine, th):
    """(motored pressure, pressure per joule of heat) [Pa] over th in [-pi, pi) (TDC firing at 0)."""
    g = eng.geometry
    gam = g.gamma
    s, ds, _ = _kinematics(g, th)
    V = g.clearance_volume + g.piston_area * s
    dV = g.piston_area * ds
    x = np.clip((th - eng.combustion_start) / eng.combustion_duration, 0.0, 1.0)
    xb = 1.0 - np.exp(-eng.wiebe_a * x ** (eng.wiebe_m + 1.0))
    dxb = np.gradient(xb, th)
    p0 = np.empty_like(th)
    p1 = np.empty_like(th)
    p0[0] = eng.intake_pressure
    p1[0] = 0.0
    h = th[1] - th[0]
    for i in range(len(th) - 1):  # Heun steps of the linear ODE
        for arr, src in ((p0, 0.0), (p1, 1.0)):
            f0 = (gam - 1) / V[i] * src * dxb[i] - gam * arr[i] / V[i] * dV[i]
            pe = arr[i] + h * f0
            f1 = (gam - 1) / V[i + 1] * src * dxb[i + 1] - gam * pe / V[i + 1] * dV[i + 1]
            arr[i + 1] = arr[i] + 0.5 * h * (f0 + f1)
    return p0, p1


def fired_engine_torque(speed: float, mean_torque: float, engine: FiredEngine | None = None):
    """Flywheel torque of the fired engine over one 720 deg cycle on a rigid crank.

    speed [rad/s], mean_torque [N m] (brake, > 0). Returns (crank angle [rad] 0..4 pi,
    torque [N m], cylinder-1 pressure [Pa], peak pressure [Pa]).
    """
    eng = engine or FiredEngine()
    if not (math.isfinite(speed) and speed > 0):
        raise InputError(f"speed = {speed!r} rad/s: accepted is a positive speed")
    if not (math.isfinite(mean_torque) and 0 < mean_torque <= 600):
        raise InputError(f"mean torque {mean_torque!r} N m: accepted is 0 < T <= 600 N m for the fired engine")
    g, fr = eng.geometry, eng.friction
    th = np.linspace(-math.pi, math.pi, N_CYCLE // 2 + 1)
    p0, p1 = _pressure_traces(eng, th)
    # one cylinder's cycle on 720 deg: the closed part above, gas exchange at the inlet
    # pressure (compression/expansion strokes -pi..pi, exchange pi..3pi)
    full = np.linspace(-math.pi, 3 * math.pi, N_CYCLE, endpoint=False)
    _, ds, dds = _kinematics(g, full)
    cl = full < math.pi
    base0 = np.where(cl, np.interp(full, th, p0), eng.intake_pressure)
    base1 = np.where(cl, np.interp(full, th, p1), 0.0)
    om = speed
    vp = ds * om
    t_in = -g.reciprocating_mass * ds * dds * om * om

    def cyl_torque(pressure):
        pg = pressure - fr.atmosphere
        f_ring = fr.ring_viscous * vp + fr.ring_boundary * (fr.ring_tension + np.maximum(pg, 0) * math.pi * g.bore * fr.ring_height) * np.tanh(vp / fr.ring_speed_ref)
        return pg * g.piston_area * ds + t_in - f_ring * ds - fr.bearing_viscous * om

    def engine_torque(q_heat):
        one = cyl_torque(base0 + q_heat * base1)
        shift = N_CYCLE // 4  # 180 deg in samples
        return sum(np.roll(one, k * shift) for k in range(4)), base0 + q_heat * base1

    t0, _ = engine_torque(0.0)
    t1, _ = engine_torque(1000.0)
    q = 1000.0 * (mean_torque - t0.mean()) / (t1.mean() - t0.mean())
    torque, p = engine_torque(q)
    angle = np.linspace(0.0, 4 * math.pi, N_CYCLE, endpoint=False)
    return angle, np.roll(torque, -N_CYCLE // 4), np.roll(p, -N_CYCLE // 4), float(p.max())


def engine_orders(speed: float, mean_torque: float, engine: FiredEngine | None = None, orders=ORDERS):
    """[(order, amplitude N m, phase rad)] of the fired engine's flywheel torque."""
    _, torque, _, _ = fired_engine_torque(speed, mean_torque, engine)
    c = np.fft.rfft(torque) / len(torque)
    out = []
    for k in orders:
        idx = int(round(2 * k))  # the cycle spans two revolutions
        out.append((float(k), float(2 * abs(c[idx])), float(np.angle(c[idx]))))
    return out


def fired_engine_excitation(speed: float, mean_torque: float, engine: FiredEngine | None = None, orders=ORDERS,
                            min_amplitude: float = 0.5):
    """OrderSum of the fired engine at ``speed`` [rad/s] and ``mean_torque`` [N m]
    (orders below ``min_amplitude`` N m dropped)."""

    content = [o for o in engine_orders(speed, mean_torque, engine, orders) if o[1] >= min_amplitude]
    return OrderSum(speed=speed, mean_torque=mean_torque, orders=tuple(content))


def wot_campaign(n: int = 17, curve=None, engine: FiredEngine | None = None):
    """Fired-engine OrderSums along the WOT torque curve (default 1200-2800 rpm, 100 rpm
    steps): the "full campaign" the mapping study predicts ([thesis] §7.1.3)."""

    curve = curve or default_torque_curve()
    w, tq = curve.sample(n)
    return [fired_engine_excitation(float(a), float(b), engine) for a, b in zip(w, tq)]


__all__ = ["fired_engine_torque", "engine_orders", "fired_engine_excitation", "wot_campaign", "ORDERS"]
