"""Magnification maps over (excitation frequency, mean torque) ([thesis] §6.3.1, §7.1.3, §7.2).

The thesis condenses a whole campaign into one picture: the magnification ratio MR of every
(test point, order) is placed at the order's excitation frequency and the point's mean
torque, repeated points are averaged, and the scattered values are interpolated onto a
regular grid. Its maps span 30-200 Hz, where the rig's data were dense ([thesis] §6.3.1,
Fig. 6.20-6.21). Regions with MR > 1 amplify the vibration; the engine's full-load curve is
drawn over the map, converted to the frequency of one order, to show where the damper
normally operates ([thesis] §6.3.1, §7.1.3 Fig. 7.16).

Input is any sweep table (see :mod:`dampersim.analysis.colourmap`); nothing simulates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from dampersim.analysis.colourmap import check_sweep_table
from dampersim.errors import InputError
from dampersim.units import rad_s_to_rpm

#: Frequency range of the thesis's maps [Hz] ([thesis] §6.3.1).
DEFAULT_FREQUENCY_RANGE_HZ = (30.0, 200.0)
#: Default grid steps: 1 Hz along frequency, 5 N m along mean torque.
DEFAULT_FREQUENCY_STEP_HZ = 1.0
DEFAULT_TORQUE_STEP_NM = 5.0
#: Test points closer than these are "the same test point" and averaged.
DEFAULT_FREQUENCY_TOL_HZ = 1e-3
DEFAULT_TORQUE_TOL_NM = 1e-3


def average_duplicates(table, value: str = "magnification", frequency_tol_hz: float = DEFAULT_FREQUENCY_TOL_HZ, torque_tol_nm: float = DEFAULT_TORQUE_TOL_NM) -> pd.DataFrame:
    """Average test points that share excitation frequency and mean torque ([thesis] §6.3.1).

    Args:
        table: DataFrame with ``frequency_hz`` [Hz], ``mean_torque_nm`` [N m] and ``value``
            (default ``magnification`` [-]); other numeric columns are averaged too.
        frequency_tol_hz, torque_tol_nm: points whose frequency and mean torque round to the
            same multiple of these steps [Hz, N m] are one test point.

    Returns:
        DataFrame with one row per distinct point: the mean of every numeric column and
        ``n_points`` (how many rows were averaged). Rows whose ``value`` is NaN are dropped
        first (e.g. orders without input).
    """
    check_sweep_table(table, ("frequency_hz", "mean_torque_nm", value))
    for name, tol in (("frequency_tol_hz", frequency_tol_hz), ("torque_tol_nm", torque_tol_nm)):
        if not (np.isfinite(tol) and tol > 0):
            raise InputError(f"{name} = {tol!r}: accepted is a positive tolerance")
    data = table[np.isfinite(table[value].to_numpy(dtype=float))]
    if data.empty:
        raise InputError(f"no finite {value!r} values in the table: nothing to map")
    numeric = [c for c in data.columns if pd.api.types.is_numeric_dtype(data[c])]
    keys = pd.DataFrame(
        {
            "_f": np.round(data["frequency_hz"].to_numpy(float) / frequency_tol_hz).astype(np.int64),
            "_t": np.round(data["mean_torque_nm"].to_numpy(float) / torque_tol_nm).astype(np.int64),
        },
        index=data.index,
    )
    grouped = pd.concat([data[numeric], keys], axis=1).groupby(["_f", "_t"], sort=True)
    out = grouped[numeric].mean()
    out["n_points"] = grouped.size()
    return out.reset_index(drop=True)


@dataclass(frozen=True, eq=False)
class MagnificationMap:
    """MR on a regular (frequency, mean torque) grid.

    frequency_hz: grid [Hz], shape (n_f,); mean_torque_nm: grid [N m], shape (n_t,);
    magnification: MR [-], shape (n_t, n_f) (rows: torque), NaN outside the convex hull of
    the test points; points: the averaged test points used (frequency_hz, mean_torque_nm,
    magnification, n_points, ...).
    """

    frequency_hz: np.ndarray
    mean_torque_nm: np.ndarray
    magnification: np.ndarray
    points: pd.DataFrame

    @property
    def above_one(self) -> np.ndarray:
        """Boolean mask (n_t, n_f): MR > 1 (the damper amplifies); False where NaN."""
        with np.errstate(invalid="ignore"):
            return np.isfinite(self.magnification) & (self.magnification > 1.0)

    def at(self, frequency_hz, mean_torque_nm):
        """MR [-] at (frequency [Hz], mean torque [N m]) by bilinear interpolation of the
        grid; NaN outside the grid or where a neighbouring node is NaN."""
        from scipy.interpolate import RegularGridInterpolator

        f = np.asarray(frequency_hz, dtype=float)
        t = np.asarray(mean_torque_nm, dtype=float)
        f, t = np.broadcast_arrays(f, t)
        interp = RegularGridInterpolator((self.mean_torque_nm, self.frequency_hz), self.magnification, bounds_error=False, fill_value=np.nan)
        out = interp(np.stack([t.ravel(), f.ravel()], axis=-1)).reshape(f.shape)
        return float(out) if out.ndim == 0 else out


def _grid(lo, hi, step, name, unit):
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        raise InputError(f"{name} = ({lo!r}, {hi!r}) {unit}: accepted is a finite range with low < high")
    if not (np.isfinite(step) and step > 0):
        raise InputError(f"{name} step {step!r} {unit}: accepted is a positive step")
    n = int(round((hi - lo) / step)) + 1
    return np.linspace(lo, hi, max(n, 2))


def magnification_map(
    table,
    frequency_range_hz=DEFAULT_FREQUENCY_RANGE_HZ,
    torque_range_nm=None,
    frequency_step_hz: float = DEFAULT_FREQUENCY_STEP_HZ,
    torque_step_nm: float = DEFAULT_TORQUE_STEP_NM,
    orders=None,
    rescale: bool = True,
    frequency_tol_hz: float = DEFAULT_FREQUENCY_TOL_HZ,
    torque_tol_nm: float = DEFAULT_TORQUE_TOL_NM,
) -> MagnificationMap:
    """Magnification map MR(frequency, mean torque) from any set of test points.

    Steps ([thesis] §6.3.1): keep the chosen orders, average duplicate points
    (:func:`average_duplicates`), interpolate linearly on a regular grid with
    ``scipy.interpolate.griddata`` (Delaunay triangulation of the points; NaN outside
    their convex hull, never extrapolated).

    Args:
        table: sweep table with ``frequency_hz`` [Hz], ``mean_torque_nm`` [N m],
            ``magnification`` [-] (and ``order`` when ``orders`` is given).
        frequency_range_hz: (low, high) of the grid [Hz]; default 30-200 Hz as the thesis.
        torque_range_nm: (low, high) of the grid [N m]; default: the points' range.
        frequency_step_hz, torque_step_nm: grid steps [Hz, N m] (rounded so the range
            ends on a node).
        orders: keep only these orders [-]; default all.
        rescale: triangulate in coordinates scaled to the unit square (Hz and N m are not
            comparable; without it the triangles would follow the larger numbers).
        frequency_tol_hz, torque_tol_nm: duplicate tolerance, see :func:`average_duplicates`.

    Returns:
        :class:`MagnificationMap`.
    """
    from scipy.interpolate import griddata

    check_sweep_table(table, ("frequency_hz", "mean_torque_nm", "magnification"))
    data = table
    if orders is not None:
        check_sweep_table(table, ("order",))
        k = np.atleast_1d(np.asarray(orders, dtype=float))
        data = data[np.isclose(data["order"].to_numpy(float)[:, None], k[None, :]).any(axis=1)]
        if data.empty:
            raise InputError(f"orders {k.tolist()} are not in the table: accepted are {sorted(set(table['order']))}")
    points = average_duplicates(data, "magnification", frequency_tol_hz, torque_tol_nm)
    f_lo, f_hi = (float(x) for x in frequency_range_hz)
    freq = _grid(f_lo, f_hi, float(frequency_step_hz), "frequency_range_hz", "Hz")
    if torque_range_nm is None:
        t_lo, t_hi = float(points["mean_torque_nm"].min()), float(points["mean_torque_nm"].max())
        if t_hi <= t_lo:
            raise InputError(f"all test points are at one mean torque ({t_lo:g} N m): a map needs at least two torques")
    else:
        t_lo, t_hi = (float(x) for x in torque_range_nm)
    torque = _grid(t_lo, t_hi, float(torque_step_nm), "torque_range_nm", "N m")
    if len(points) < 3:
        raise InputError(f"only {len(points)} distinct test points: a map needs at least 3 not on one line")
    xy = points[["frequency_hz", "mean_torque_nm"]].to_numpy(float)
    ff, tt = np.meshgrid(freq, torque)
    try:
        mr = griddata(xy, points["magnification"].to_numpy(float), (ff, tt), method="linear", rescale=rescale)
    except Exception as exc:  # Qhull: all points on a line, etc.
        raise InputError(f"cannot triangulate the test points (are they all on one line?): {exc}") from None
    return MagnificationMap(freq, torque, mr, points)


def torque_curve_overlay(curve, order: float, n: int = 161, frequency_range_hz=None) -> pd.DataFrame:
    """An engine torque curve drawn on a map: (frequency of one order, mean torque).

    Args:
        curve: a :class:`dampersim.excitation.torque_curve.TorqueCurve`.
        order: engine order whose frequency f = order * speed / (2 pi) is used [-].
        n: points along the curve.
        frequency_range_hz: optionally drop points outside (low, high) [Hz].

    Returns:
        DataFrame with speed_rad_s, speed_rpm, order, frequency_hz, mean_torque_nm.
    """
    if not (np.isfinite(order) and order > 0):
        raise InputError(f"order {order!r}: accepted is a positive engine order")
    w, tq = curve.sample(n)
    out = pd.DataFrame(
        {
            "speed_rad_s": w,
            "speed_rpm": rad_s_to_rpm(w),
            "order": float(order),
            "frequency_hz": float(order) * w / (2 * np.pi),
            "mean_torque_nm": tq,
        }
    )
    if frequency_range_hz is not None:
        lo, hi = frequency_range_hz
        out = out[(out["frequency_hz"] >= lo) & (out["frequency_hz"] <= hi)].reset_index(drop=True)
    return out


def predict_along_curve(mmap: MagnificationMap, curve, order: float, n: int = 161) -> pd.DataFrame:
    """MR predicted from a map along a torque curve for one order ([thesis] §7.1.3, Fig. 7.16).

    Returns :func:`torque_curve_overlay` plus a ``magnification`` column [-] read from the
    map (NaN where the curve leaves the map).
    """
    out = torque_curve_overlay(curve, order, n)
    out["magnification"] = mmap.at(out["frequency_hz"].to_numpy(), out["mean_torque_nm"].to_numpy())
    return out


__all__ = [
    "DEFAULT_FREQUENCY_RANGE_HZ",
    "MagnificationMap",
    "average_duplicates",
    "magnification_map",
    "torque_curve_overlay",
    "predict_along_curve",
]


def zone_summary(table, knee_nm: float, orders=None, spike_hz: float = 20.0, low_hz: float = 30.0, mid_hz: float = 80.0) -> dict:
    """MR statistics in the zones the thesis describes ([thesis] §7.2, docs/model.md §10),
    from the test points themselves (no interpolation).

    Zones: ``spike`` f < spike_hz; ``low`` f < low_hz; ``below_knee_high`` mean torque <
    knee_nm and f > mid_hz (both sets active: the trough); ``above_knee_high`` mean torque
    > knee_nm and f > mid_hz (inner set only). Each zone reports the number of points,
    median, maximum and the share of points with MR > 1. ``knee_nm`` [N m]; frequencies [Hz].
    """
    t = table.dropna(subset=["magnification"])
    if orders is not None:
        t = t[t["order"].isin([float(k) for k in orders])]
    f = t["frequency_hz"].to_numpy()
    m = t["mean_torque_nm"].to_numpy()
    mr = t["magnification"].to_numpy()
    zones = {
        "spike": f < spike_hz,
        "low": f < low_hz,
        "below_knee_high": (m < knee_nm) & (f > mid_hz),
        "above_knee_high": (m > knee_nm) & (f > mid_hz),
    }
    out = {}
    for name, sel in zones.items():
        vals = mr[sel]
        out[name] = {
            "points": int(vals.size),
            "median_mr": float(np.median(vals)) if vals.size else None,
            "max_mr": float(np.max(vals)) if vals.size else None,
            "share_above_one": float(np.mean(vals > 1.0)) if vals.size else None,
        }
    return out
