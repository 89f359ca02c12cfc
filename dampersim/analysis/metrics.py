"""Per-order metrics comparing damper input, output and simulation ([thesis] §3.4, §6.3.1).

All functions work on per-order amplitude arrays [N m] as returned by
:func:`dampersim.signal.order_amplitudes`, element by element; any array shape is
accepted as long as the arguments match.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from dampersim.errors import InputError

#: Input amplitudes below this [N m] give NaN instead of a ratio.
DEFAULT_MIN_INPUT = 1e-9


def _amplitudes(values, name):
    """``values`` as a float array of amplitudes (>= 0 or NaN for "not available")."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of order amplitudes in N m: {exc}") from exc
    if np.any(arr < 0) or np.any(np.isinf(arr)):
        raise InputError(
            f"{name} must hold amplitudes >= 0 in N m (NaN for a missing order), "
            f"got {arr.tolist()}"
        )
    return arr


def _same_shape(**arrays):
    shapes = {name: arr.shape for name, arr in arrays.items()}
    if len(set(shapes.values())) > 1:
        raise InputError(f"arrays must have one value per order and the same shape, got {shapes}")


def _min_input(min_input):
    try:
        value = float(min_input)
    except (TypeError, ValueError):
        value = float("nan")
    if not (np.isfinite(value) and value >= 0):
        raise InputError(f"min_input must be a finite amplitude >= 0 in N m, got {min_input!r}")
    return value


def _divide_by_input(numerator, input_amp, min_input):
    """numerator / input_amp, NaN where input_amp < min_input, is 0 or NaN (no warnings)."""
    ratio = np.full(numerator.shape, np.nan)
    ok = (input_amp >= min_input) & (input_amp > 0)
    np.divide(numerator, input_amp, out=ratio, where=ok)
    return ratio


def magnification_ratio(input_amp, output_amp, min_input=DEFAULT_MIN_INPUT):
    """Magnification ratio per engine order: output amplitude / input amplitude.

    The damper's filtering per order as used throughout the thesis: an MR below 1 means the
    damper attenuates that order ([thesis] §3.4 for how the order amplitudes are obtained).

    Args:
        input_amp: order amplitudes of the torque entering the damper [N m].
        output_amp: order amplitudes of the torque leaving it [N m], same shape.
        min_input: input amplitudes below this [N m] give NaN (the order is not excited, so
            its ratio is meaningless); never divides by zero.

    Returns:
        Float array of ratios [-], NaN where the input is below ``min_input`` or missing.

    Raises:
        ValueError: shapes differ, negative or infinite amplitudes, bad ``min_input``.
    """
    inp = _amplitudes(input_amp, "input_amp")
    out = _amplitudes(output_amp, "output_amp")
    _same_shape(input_amp=inp, output_amp=out)
    return _divide_by_input(out, inp, _min_input(min_input))


def simulation_error(sim_out, meas_out, meas_in, min_input=DEFAULT_MIN_INPUT):
    """Error of simulated against measured output order amplitudes ([thesis] §6.3.1).

    The thesis judges the model by the absolute difference between simulated and measured
    output amplitude of each order, expressed relative to the measured *input* amplitude of
    that order, so that well-attenuated orders (small output) do not inflate the error.

    Args:
        sim_out: simulated output order amplitudes [N m].
        meas_out: measured output order amplitudes [N m], same shape.
        meas_in: measured input order amplitudes [N m], same shape.
        min_input: measured input amplitudes below this [N m] give a NaN relative error.

    Returns:
        dict with ``"abs_nm"``: ``|sim_out - meas_out|`` [N m], and
        ``"relative_to_input"``: ``abs_nm / meas_in`` [-] (a fraction; x100 for percent),
        NaN where ``meas_in`` is below ``min_input``.

    Raises:
        ValueError: shapes differ, negative or infinite amplitudes, bad ``min_input``.
    """
    sim = _amplitudes(sim_out, "sim_out")
    meas = _amplitudes(meas_out, "meas_out")
    inp = _amplitudes(meas_in, "meas_in")
    _same_shape(sim_out=sim, meas_out=meas, meas_in=inp)
    abs_nm = np.abs(sim - meas)
    return {
        "abs_nm": abs_nm,
        "relative_to_input": _divide_by_input(abs_nm, inp, _min_input(min_input)),
    }


def error_table(errors_by_point, orders=None):
    """Minimum, mean and maximum error per order over a test campaign ([thesis] §6.3.1).

    Args:
        errors_by_point: mapping from test point id to a 1-D array of per-order errors
            (e.g. ``simulation_error(...)["relative_to_input"]`` [-] or ``["abs_nm"]``
            [N m]); all arrays the same length. NaN entries (order not excited) are skipped.
        orders: engine order labels for the rows; default 1, 2, ..., n.

    Returns:
        pandas DataFrame indexed by ``order`` with columns ``min``, ``mean``, ``max`` (unit
        of the errors); NaN for an order without any finite value.

    Raises:
        ValueError: empty mapping, arrays of different lengths or not 1-D, or ``orders`` of
            the wrong length.
    """
    if not isinstance(errors_by_point, Mapping) or not errors_by_point:
        raise InputError(
            "errors_by_point must be a non-empty mapping {test point id: per-order errors}"
        )
    rows = {}
    for point, values in errors_by_point.items():
        try:
            arr = np.asarray(values, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"test point {point!r}: errors must be numbers: {exc}") from exc
        if arr.ndim != 1:
            raise InputError(f"test point {point!r}: expected a 1-D array of per-order errors, "
                             f"got shape {arr.shape}")
        rows[point] = arr
    lengths = {point: arr.size for point, arr in rows.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"all test points need the same number of orders, got {lengths}")
    n = next(iter(lengths.values()))
    labels = np.arange(1, n + 1) if orders is None else np.asarray(orders)
    if labels.shape != (n,):
        raise InputError(f"orders has {labels.size} labels but the errors have {n} orders")
    frame = pd.DataFrame(np.vstack(list(rows.values())), columns=pd.Index(labels, name="order"))
    table = frame.agg(["min", "mean", "max"]).T
    table.columns.name = None
    return table
