"""Order table of one record: input and output order amplitudes and the magnification
ratio per engine order over the analysis window ([thesis] §3.4)."""

from __future__ import annotations

import math

import numpy as np

from dampersim.analysis.metrics import magnification_ratio
from dampersim.signal import order_amplitudes

#: Orders whose amplitudes the table always reports.
REPORT_ORDERS = tuple(float(k) for k in range(1, 9))
#: Magnification is not reported for orders whose input is below this share of the
#: largest input order (the order is not excited; same rule as the sweep tables).
MIN_INPUT_REL = 1e-3


def _finite(v):
    v = float(v)
    return v if math.isfinite(v) else None


def order_table(result, excited_orders, seconds: float) -> list:
    """Rows {order, frequency_hz, input_nm, output_nm, mr, excited} for orders 1-8 and every
    excited order (input and output amplitudes over the analysis window, [thesis] §3.4).

    ``result`` needs ``window(seconds)``, ``sample_rate`` [Hz], ``speed`` [rad/s],
    ``input_torque`` and ``output_torque`` [N m] (a SimulationResult); orders at or above
    the Nyquist frequency are left out; ``mr`` is None where the input is not excited.
    """
    w = result.window(seconds)
    fs = result.sample_rate
    x_in, x_out = result.input_torque[w], result.output_torque[w]
    f1 = result.speed / (2 * math.pi)
    nyq = fs / 2
    whole = [k for k in REPORT_ORDERS if k * f1 < nyq]
    amps = {}
    if whole:
        a_in = order_amplitudes(x_in, fs, result.speed, whole)
        a_out = order_amplitudes(x_out, fs, result.speed, whole)
        amps.update({k: (a, b) for k, a, b in zip(whole, a_in, a_out)})
    for k in excited_orders:
        if k in amps or k * f1 >= nyq:
            continue
        a, = order_amplitudes(x_in, fs, result.speed, [k])
        b, = order_amplitudes(x_out, fs, result.speed, [k])
        amps[k] = (a, b)
    ks = sorted(amps)
    a_in = np.array([amps[k][0] for k in ks])
    a_out = np.array([amps[k][1] for k in ks])
    largest = float(np.max(a_in)) if a_in.size else 0.0
    mr = magnification_ratio(a_in, a_out, min_input=max(MIN_INPUT_REL * largest, 1e-12))
    rows = []
    for k, ai, ao, m in zip(ks, a_in, a_out, mr):
        rows.append({
            "order": float(k),
            "frequency_hz": float(k * f1),
            "input_nm": float(ai),
            "output_nm": float(ao),
            "mr": _finite(m),
            "excited": bool(any(abs(k - e) < 1e-9 for e in excited_orders)),
        })
    return rows


__all__ = ["REPORT_ORDERS", "MIN_INPUT_REL", "order_table"]
