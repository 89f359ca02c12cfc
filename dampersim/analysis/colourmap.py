"""FFT colourmaps, order lines and order cuts of a speed sweep ([thesis] §3.4, §6.3.1).

A speed sweep gives one amplitude spectrum per speed point (the Hann spectrum of the last
1.25 s, [thesis] §3.4). Stacked over speed they form the *FFT colourmap*: amplitude over
(speed, frequency), where engine orders appear as straight lines f = k * speed / (2 pi)
through the origin and resonances as horizontal bands ([thesis] §6.3.1, Fig. 6.12-6.13).
The *order cuts* are the order amplitudes read along those lines, plotted against speed
together with the input amplitude for context ([thesis] §6.3.1, Fig. 6.14-6.15).

Everything here is a pure function of arrays or pandas DataFrames; nothing simulates.

Sweep tables (one row per test point and order) use the columns of :data:`SWEEP_COLUMNS`:
``speed_rpm``, ``speed_rad_s``, ``mean_torque_nm``, ``order``, ``frequency_hz``,
``input_amplitude_nm``, ``output_amplitude_nm``, ``magnification``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from dampersim.signal import DEFAULT_ORDERS, amplitude_spectrum
from dampersim.errors import InputError
from dampersim.units import rad_s_to_rpm
from dampersim.analysis.metrics import magnification_ratio

#: Columns of a sweep table (SI plus rpm for display).
SWEEP_COLUMNS = (
    "speed_rpm",
    "speed_rad_s",
    "mean_torque_nm",
    "order",
    "frequency_hz",
    "input_amplitude_nm",
    "output_amplitude_nm",
    "magnification",
)
#: Largest colourmap matrix we build (cells); beyond it, ask for a lower f_max_hz.
MAX_CELLS = 20_000_000
#: Speeds closer than this [rad/s] are the same speed point (duplicates are averaged).
SPEED_TOL_RAD_S = 1e-6
#: Default tolerance [N m] for repeats of a test point in an order cut: the thesis reports
#: mean-torque errors of the rig of a few per cent ([thesis] §3.3.2, Fig. 3.12-3.13).
DEFAULT_TORQUE_TOL_NM = 5.0


# --- sweep tables ------------------------------------------------------------------------
def check_sweep_table(table, required=SWEEP_COLUMNS) -> pd.DataFrame:
    """Return ``table`` as a DataFrame after checking it has the ``required`` columns.

    Raises :class:`InputError` naming the missing columns and the accepted set.
    """
    if not isinstance(table, pd.DataFrame):
        raise InputError(f"sweep table: accepted is a pandas DataFrame with columns {list(SWEEP_COLUMNS)}, got {type(table).__name__}")
    missing = [c for c in required if c not in table.columns]
    if missing:
        raise InputError(f"sweep table lacks columns {missing}: accepted is a table with {list(required)}")
    for c in required:
        if not pd.api.types.is_numeric_dtype(table[c]):
            raise InputError(f"sweep table column {c!r} must be numeric, got dtype {table[c].dtype}")
    return table


def sweep_table(speeds_rad_s, mean_torques_nm, input_amplitudes_nm, output_amplitudes_nm, orders=DEFAULT_ORDERS, min_input_nm=1e-9) -> pd.DataFrame:
    """Build a sweep table from per-point order amplitudes.

    Args:
        speeds_rad_s: speed of each test point [rad/s], shape (n,).
        mean_torques_nm: mean input torque of each point [N m], shape (n,) or scalar.
        input_amplitudes_nm, output_amplitudes_nm: order amplitudes [N m], shape (n, n_orders)
            (rows: test points, columns: ``orders``), e.g. from
            :meth:`dampersim.SimulationResult.order_amplitudes`.
        orders: engine orders of the columns [-].
        min_input_nm: input amplitudes below this [N m] give NaN magnification.

    Returns:
        DataFrame with :data:`SWEEP_COLUMNS`, one row per point and order.
    """

    w = np.atleast_1d(np.asarray(speeds_rad_s, dtype=float))
    tq = np.broadcast_to(np.asarray(mean_torques_nm, dtype=float), w.shape)
    k = np.atleast_1d(np.asarray(orders, dtype=float))
    a_in = np.asarray(input_amplitudes_nm, dtype=float).reshape(w.size, -1)
    a_out = np.asarray(output_amplitudes_nm, dtype=float).reshape(w.size, -1)
    if a_in.shape != (w.size, k.size) or a_out.shape != a_in.shape:
        raise InputError(
            f"amplitudes must have shape (points, orders) = ({w.size}, {k.size}), "
            f"got input {a_in.shape} and output {a_out.shape}"
        )
    if np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise InputError("speeds_rad_s must be positive finite speeds in rad/s")
    mr = magnification_ratio(a_in, a_out, min_input=min_input_nm)
    ww = np.repeat(w, k.size)
    kk = np.tile(k, w.size)
    return pd.DataFrame(
        {
            "speed_rpm": rad_s_to_rpm(ww),
            "speed_rad_s": ww,
            "mean_torque_nm": np.repeat(tq, k.size),
            "order": kk,
            "frequency_hz": kk * ww / (2.0 * np.pi),
            "input_amplitude_nm": a_in.ravel(),
            "output_amplitude_nm": a_out.ravel(),
            "magnification": mr.ravel(),
        }
    )


# --- colourmaps --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Colourmap:
    """Amplitude over (speed, frequency) of one signal of a speed sweep.

    speed_rad_s: sorted speed points [rad/s], shape (n_speed,);
    frequency_hz: common frequency grid [Hz], shape (n_freq,);
    amplitude_nm: amplitude [N m], shape (n_speed, n_freq), NaN where a spectrum does not
    reach that frequency; label: e.g. "input" or "output".
    """

    speed_rad_s: np.ndarray
    frequency_hz: np.ndarray
    amplitude_nm: np.ndarray
    label: str = ""

    @property
    def speed_rpm(self) -> np.ndarray:
        """Speed points [rpm]."""
        return rad_s_to_rpm(self.speed_rad_s)

    def limit(self, f_max_hz: float) -> "Colourmap":
        """The same map cut to frequencies <= ``f_max_hz`` [Hz]."""
        keep = self.frequency_hz <= f_max_hz
        return Colourmap(self.speed_rad_s, self.frequency_hz[keep], self.amplitude_nm[:, keep], self.label)


def _as_spectra(spectra):
    """Normalise the accepted spectrum containers to a list of (speed, freq, amp) arrays."""
    if isinstance(spectra, pd.DataFrame):
        need = ("speed_rad_s", "frequency_hz", "amplitude_nm")
        check_sweep_table(spectra, need)
        out = []
        for speed, grp in spectra.groupby("speed_rad_s", sort=True):
            grp = grp.sort_values("frequency_hz")
            out.append((float(speed), grp["frequency_hz"].to_numpy(float), grp["amplitude_nm"].to_numpy(float)))
        spectra = out
    form = "a list of (speed [rad/s], frequency [Hz] array, amplitude [N m] array) or a long DataFrame with speed_rad_s, frequency_hz, amplitude_nm"
    try:
        items = list(spectra)
    except TypeError:
        raise InputError(f"spectra: accepted is {form}") from None
    if not items:
        raise InputError(f"spectra is empty: accepted is {form}")
    out = []
    for i, item in enumerate(items):
        if isinstance(item, dict):
            item = (item.get("speed_rad_s"), item.get("frequency_hz"), item.get("amplitude_nm"))
        try:
            speed, freq, amp = item
            speed = float(speed)
            freq = np.asarray(freq, dtype=float)
            amp = np.asarray(amp, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"spectra[{i}]: accepted is {form}") from None
        if not (np.isfinite(speed) and speed > 0):
            raise InputError(f"spectra[{i}]: speed {speed!r} rad/s: accepted is a positive finite speed")
        if freq.ndim != 1 or freq.shape != amp.shape or freq.size < 2:
            raise InputError(f"spectra[{i}]: frequency and amplitude must be 1-D arrays of equal length >= 2, got {freq.shape} and {amp.shape}")
        if not np.all(np.isfinite(freq)) or np.any(np.diff(freq) <= 0):
            raise InputError(f"spectra[{i}]: frequencies must be finite and strictly increasing [Hz]")
        out.append((speed, freq, amp))
    return out


def spectrum_record(speed_rad_s, signal_nm, sample_rate_hz):
    """(speed [rad/s], frequency [Hz], amplitude [N m]) of one record, ready for
    :func:`colourmap` (Hann amplitude spectrum, [thesis] §3.4)."""
    f, a = amplitude_spectrum(signal_nm, sample_rate_hz)
    return float(speed_rad_s), f, a


def spectra_from_results(results, signal: str = "output", seconds: float = 1.25):
    """Spectra of the analysis window (last ``seconds`` [s]) of existing simulation results.

    ``signal`` is "input" or "output" (torque at the damper input or output transducer).
    Only analyses the given results; it never runs a simulation.
    """
    attr = {"input": "input_torque", "output": "output_torque"}.get(signal)
    if attr is None:
        raise InputError(f"signal {signal!r}: accepted is 'input' or 'output'")
    out = []
    for r in results:
        w = r.window(seconds)
        out.append(spectrum_record(r.speed, getattr(r, attr)[w], r.sample_rate))
    return out


def common_frequency_grid(spectra, f_max_hz=None, df_hz=None) -> np.ndarray:
    """Frequency grid [Hz] shared by all ``spectra``.

    If every spectrum has the same bins and no ``f_max_hz``/``df_hz`` is asked for, those
    bins are returned (no interpolation). Otherwise the grid runs from 0 Hz in steps of
    ``df_hz`` (default: the finest bin spacing among the spectra, so no detail is lost) up
    to ``f_max_hz`` (default: the lowest top frequency among the spectra, so no spectrum is
    extrapolated).
    """
    spectra = _as_spectra(spectra)
    first = spectra[0][1]
    same = all(s[1].shape == first.shape and np.array_equal(s[1], first) for s in spectra)
    if same and f_max_hz is None and df_hz is None:
        return first.copy()
    if same and df_hz is None:
        return first[first <= f_max_hz].copy()
    if df_hz is None:
        df_hz = min(float(np.median(np.diff(s[1]))) for s in spectra)
    if f_max_hz is None:
        f_max_hz = min(float(s[1][-1]) for s in spectra)
    df_hz, f_max_hz = float(df_hz), float(f_max_hz)
    if not (np.isfinite(df_hz) and df_hz > 0 and np.isfinite(f_max_hz) and f_max_hz > df_hz):
        raise InputError(f"frequency grid: accepted is df_hz > 0 and f_max_hz > df_hz [Hz], got df_hz={df_hz!r}, f_max_hz={f_max_hz!r}")
    n = int(np.floor(f_max_hz / df_hz + 1e-9)) + 1
    return np.arange(n) * df_hz


def colourmap(spectra, frequency_hz=None, f_max_hz=None, df_hz=None, label: str = "") -> Colourmap:
    """FFT colourmap matrix amplitude(speed, frequency) ([thesis] §3.4, §6.3.1).

    Args:
        spectra: per-speed spectra, either a list of (speed [rad/s], frequency [Hz] array,
            amplitude [N m] array) or a long DataFrame with columns ``speed_rad_s``,
            ``frequency_hz``, ``amplitude_nm``.
        frequency_hz: frequency grid [Hz] to use; default :func:`common_frequency_grid`.
        f_max_hz, df_hz: top frequency and spacing [Hz] of the default grid.
        label: name stored with the map ("input", "output", ...).

    Spectra on other bins are linearly interpolated onto the grid; grid frequencies beyond a
    spectrum's range are NaN. Spectra at the same speed (within 1e-6 rad/s) are averaged.

    Returns:
        :class:`Colourmap` with speeds sorted ascending.
    """
    spectra = _as_spectra(spectra)
    grid = common_frequency_grid(spectra, f_max_hz, df_hz) if frequency_hz is None else np.asarray(frequency_hz, dtype=float)
    if grid.ndim != 1 or grid.size < 2 or np.any(np.diff(grid) <= 0):
        raise InputError("frequency_hz: accepted is a strictly increasing 1-D grid of at least 2 frequencies [Hz]")
    speeds = np.array([s[0] for s in spectra])
    order = np.argsort(speeds, kind="stable")
    # group equal speeds
    keys = np.round(speeds[order] / SPEED_TOL_RAD_S).astype(np.int64)
    uniq, start = np.unique(keys, return_index=True)
    if uniq.size * grid.size > MAX_CELLS:
        raise InputError(
            f"colourmap of {uniq.size} speeds x {grid.size} frequencies is too large "
            f"(> {MAX_CELLS} cells): pass a lower f_max_hz or a coarser df_hz"
        )
    amp = np.full((uniq.size, grid.size), np.nan)
    out_speed = np.empty(uniq.size)
    bounds = list(start) + [order.size]
    for row in range(uniq.size):
        members = order[bounds[row]:bounds[row + 1]]
        stack = []
        for m in members:
            _, f, a = spectra[m]
            if f.shape == grid.shape and np.array_equal(f, grid):
                stack.append(a)
            else:
                stack.append(np.interp(grid, f, a, left=np.nan, right=np.nan))
        with np.errstate(invalid="ignore"):
            amp[row] = np.mean(stack, axis=0)
        out_speed[row] = float(np.mean(speeds[members]))
    return Colourmap(out_speed, grid, amp, label)


def colourmaps(input_spectra, output_spectra, f_max_hz=None, df_hz=None) -> dict:
    """Input and output colourmaps on one common frequency grid.

    Arguments as :func:`colourmap`; returns ``{"input": Colourmap, "output": Colourmap}``.
    """
    inp, out = _as_spectra(input_spectra), _as_spectra(output_spectra)
    grid = common_frequency_grid(inp + out, f_max_hz, df_hz)
    return {"input": colourmap(inp, grid, label="input"), "output": colourmap(out, grid, label="output")}


# --- order lines and cuts ----------------------------------------------------------------
def order_lines(speeds_rad_s, orders=DEFAULT_ORDERS, f_max_hz=None) -> pd.DataFrame:
    """Frequency of each engine order over speed: f = k * speed / (2 pi) [Hz].

    Args:
        speeds_rad_s: speeds [rad/s] (any order; returned sorted).
        orders: engine orders [-] (fractional allowed).
        f_max_hz: drop points above this frequency [Hz] (e.g. the colourmap's top).

    Returns:
        Long DataFrame with columns order, speed_rad_s, speed_rpm, frequency_hz.
    """
    w = np.sort(np.atleast_1d(np.asarray(speeds_rad_s, dtype=float)))
    k = np.atleast_1d(np.asarray(orders, dtype=float))
    if w.size == 0 or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise InputError("speeds_rad_s: accepted is one or more positive finite speeds [rad/s]")
    if k.size == 0 or not np.all(np.isfinite(k)) or np.any(k <= 0):
        raise InputError(f"orders {orders!r}: accepted is one or more positive engine orders")
    ww = np.tile(w, k.size)
    kk = np.repeat(k, w.size)
    frame = pd.DataFrame({"order": kk, "speed_rad_s": ww, "speed_rpm": rad_s_to_rpm(ww), "frequency_hz": kk * ww / (2 * np.pi)})
    if f_max_hz is not None:
        frame = frame[frame["frequency_hz"] <= float(f_max_hz)].reset_index(drop=True)
    return frame


def order_cuts(table, orders=None, mean_torque_nm=None, torque_tol_nm=DEFAULT_TORQUE_TOL_NM) -> pd.DataFrame:
    """Order amplitudes along speed, cut from a sweep table ([thesis] §6.3.1, Fig. 6.14).

    Args:
        table: sweep table (:data:`SWEEP_COLUMNS`).
        orders: orders to keep [-]; default all in the table.
        mean_torque_nm: keep only points within ``torque_tol_nm`` of this mean torque [N m]
            (needed for mapping sets, which hold several mean torques per speed).
        torque_tol_nm: points at one speed whose mean torques differ by at most this [N m]
            are repeats of one test point and are averaged.

    Returns:
        DataFrame with :data:`SWEEP_COLUMNS` plus ``n_points`` (repeats averaged), sorted by
        order then speed. Repeats are averaged column by column (the magnification is the
        mean of the repeats' ratios, as the thesis does for its maps).

    Raises:
        InputError: missing columns; several distinct mean torques at one speed and order
            without ``mean_torque_nm`` (the cut would zig-zag between operating points).
    """
    table = check_sweep_table(table)
    data = table.loc[:, list(SWEEP_COLUMNS)]
    if orders is not None:
        k = np.atleast_1d(np.asarray(orders, dtype=float))
        missing = [x for x in k if not np.any(np.isclose(data["order"], x))]
        if missing:
            raise InputError(f"orders {missing} are not in the table: accepted are {sorted(set(data['order']))}")
        data = data[np.isclose(data["order"].to_numpy()[:, None], k[None, :]).any(axis=1)]
    if mean_torque_nm is not None:
        data = data[np.abs(data["mean_torque_nm"] - float(mean_torque_nm)) <= torque_tol_nm]
        if data.empty:
            raise InputError(
                f"no test point within {torque_tol_nm:g} N m of mean torque {mean_torque_nm:g} N m: "
                f"accepted are mean torques in {sorted(set(np.round(table['mean_torque_nm'], 1)))}"
            )
    data = data.assign(_speed_key=np.round(data["speed_rad_s"] / SPEED_TOL_RAD_S).astype(np.int64))
    spread = data.groupby(["order", "_speed_key"])["mean_torque_nm"].agg(lambda s: s.max() - s.min())
    if (spread > torque_tol_nm).any():
        (k, key) = spread[spread > torque_tol_nm].index[0]
        raise InputError(
            f"order {k:g} at {rad_s_to_rpm(key * SPEED_TOL_RAD_S):.0f} rpm has test points at mean torques "
            f"{spread.loc[(k, key)]:.1f} N m apart: pass mean_torque_nm= to cut one operating line "
            f"(or raise torque_tol_nm if they are repeats)"
        )
    grouped = data.groupby(["order", "_speed_key"], sort=True)
    out = grouped[list(SWEEP_COLUMNS)].mean()
    out["n_points"] = grouped.size()
    return out.reset_index(drop=True).sort_values(["order", "speed_rad_s"]).reset_index(drop=True)


__all__ = [
    "SWEEP_COLUMNS",
    "Colourmap",
    "check_sweep_table",
    "sweep_table",
    "spectrum_record",
    "spectra_from_results",
    "common_frequency_grid",
    "colourmap",
    "colourmaps",
    "order_lines",
    "order_cuts",
]
