"""Natural frequencies, mode shapes and Campbell data of the linearised damper on the rig.

The linear model (:func:`dampersim.solver.linear.linearise`) is the frictionless mass and
stiffness description of the damper and the rig output chain about the positive-torque
contact state (docs/model.md §9, [thesis] Eq. 11). Its undamped modes explain the resonance
bands seen in the colourmaps ([thesis] §6.3.1, §7.2: ~5-10 Hz and 170-210 Hz). An engine
order k excites a mode of frequency f_n when k * rpm / 60 = f_n; the Campbell diagram draws
the order lines f = k * rpm / 60 over speed against the natural frequencies and marks
those crossings.

Linear and speed-independent: the matrices hold no centrifugal or friction terms, so the
natural frequencies are horizontal lines in the Campbell diagram.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from dampersim.errors import InputError
from dampersim.units import rad_s_to_rpm, rpm_to_rad_s
from dampersim.solver.linear import linearise

#: Orders drawn by default: the first eight, as the Peakfinder reads ([thesis] §3.4).
DEFAULT_ORDERS = tuple(range(1, 9))
#: Default Campbell speed range [rpm]: the thesis's simulated range ([thesis] §7.3, 500-3000 rpm).
DEFAULT_SPEED_RANGE_RPM = (500.0, 3000.0)
#: Modes below this fraction of the highest natural frequency (and below 1e-3 Hz) are rigid.
RIGID_TOL_HZ = 1e-3

_GROUP_RE = re.compile(r"^(.*)\[\d+\]$")


def dof_group(name: str) -> str:
    """Body a DOF belongs to: spring masses 'outer[3]' -> 'outer'; others unchanged."""
    m = _GROUP_RE.match(name)
    return m.group(1) if m else name


@dataclass(frozen=True, eq=False)
class ModalResult:
    """Undamped modes of a linear model.

    dof_names: DOF names; frequencies_hz: natural frequencies [Hz], ascending, shape (n,);
    shapes: mode shapes [-], shape (n_dof, n), each column scaled to max |value| = 1 with
    its largest entry positive; kinetic_fraction: share of each DOF in the mode's kinetic
    energy M_ii phi_i^2 / sum_j M_jj phi_j^2 [-], columns sum to 1; rigid: rigid-body modes
    (zero frequency, e.g. a free output motor); motor: "free" or "held".
    """

    dof_names: tuple
    frequencies_hz: np.ndarray
    shapes: np.ndarray
    kinetic_fraction: np.ndarray
    rigid: np.ndarray
    motor: str = "free"

    def dominant_dofs(self, mode: int, n: int = 3) -> list:
        """The ``n`` DOFs with the largest kinetic-energy share in ``mode`` (0-based index):
        list of (name, fraction [-])."""
        self._check_mode(mode)
        frac = self.kinetic_fraction[:, mode]
        idx = np.argsort(frac)[::-1][:n]
        return [(self.dof_names[i], float(frac[i])) for i in idx]

    def group_fractions(self, mode: int) -> dict:
        """Kinetic-energy share [-] of each body in ``mode``, spring masses summed per
        spring ("outer", "pair_outer", "pair_inner"), largest first."""
        self._check_mode(mode)
        acc = {}
        for name, f in zip(self.dof_names, self.kinetic_fraction[:, mode]):
            g = dof_group(name)
            acc[g] = acc.get(g, 0.0) + float(f)
        return dict(sorted(acc.items(), key=lambda kv: -kv[1]))

    def summary(self, max_frequency_hz: float | None = None, top: int = 3, include_rigid: bool = False) -> pd.DataFrame:
        """One row per mode: mode (1-based), frequency_hz, rigid, dominant (top DOFs) and
        bodies (top groups), each as "name (share %)" text; modes above
        ``max_frequency_hz`` [Hz] are left out."""
        rows = []
        for i, f in enumerate(self.frequencies_hz):
            if self.rigid[i] and not include_rigid:
                continue
            if max_frequency_hz is not None and f > max_frequency_hz:
                continue
            dom = ", ".join(f"{n} ({100 * s:.0f} %)" for n, s in self.dominant_dofs(i, top))
            grp = ", ".join(f"{n} ({100 * s:.0f} %)" for n, s in list(self.group_fractions(i).items())[:top])
            rows.append({"mode": i + 1, "frequency_hz": float(f), "rigid": bool(self.rigid[i]), "dominant": dom, "bodies": grp})
        return pd.DataFrame(rows, columns=["mode", "frequency_hz", "rigid", "dominant", "bodies"])

    def _check_mode(self, mode):
        if not (isinstance(mode, (int, np.integer)) and 0 <= mode < self.frequencies_hz.size):
            raise InputError(f"mode {mode!r}: accepted is a 0-based index below {self.frequencies_hz.size}")


def modes_from_matrices(M, K, dof_names=None, motor: str = "") -> ModalResult:
    """Undamped modes of M q'' + K q = 0 (M symmetric positive definite [kg m^2], K symmetric
    [N m/rad]) via the symmetric generalised eigenproblem (scipy.linalg.eigh)."""
    from scipy.linalg import eigh

    M = np.asarray(M, dtype=float)
    K = np.asarray(K, dtype=float)
    n = M.shape[0]
    if M.shape != (n, n) or K.shape != (n, n):
        raise InputError(f"M and K must be square and of equal size, got {M.shape} and {K.shape}")
    if not (np.allclose(M, M.T) and np.allclose(K, K.T, rtol=1e-10, atol=1e-9 * np.abs(K).max())):
        raise InputError("M and K must be symmetric for an undamped modal analysis")
    lam, vec = eigh(K, M)
    lam = np.clip(lam, 0.0, None)  # tiny negative round-off of rigid modes
    freq = np.sqrt(lam) / (2.0 * np.pi)
    order = np.argsort(freq, kind="stable")
    freq, vec = freq[order], vec[:, order]
    big = np.argmax(np.abs(vec), axis=0)
    scale = vec[big, np.arange(n)]
    shapes = vec / scale
    ke = np.diag(M)[:, None] * shapes**2
    frac = ke / ke.sum(axis=0, keepdims=True)
    rigid = freq < max(RIGID_TOL_HZ, 1e-9 * float(freq.max()) if freq.size else 0.0)
    names = tuple(dof_names) if dof_names is not None else tuple(f"dof{i}" for i in range(n))
    return ModalResult(names, freq, shapes, frac, rigid, motor)


def modal_analysis(system, motor: str = "free") -> ModalResult:
    """Natural frequencies [Hz] and mode shapes of ``system`` (a DamperSystem) on the rig.

    ``motor``: "free" (output motor inertia free: one rigid-body mode at 0 Hz) or "held"
    (speed held exactly: the motor is ground), see :func:`dampersim.solver.linear.linearise`.
    """

    if motor not in ("free", "held"):
        raise InputError(f"motor {motor!r}: accepted is 'free' or 'held'")
    lm = linearise(system, motor=motor)
    return modes_from_matrices(lm.M, lm.K, lm.dof_names, motor)


@dataclass(frozen=True, eq=False)
class CampbellData:
    """Order lines and natural frequencies over speed.

    natural_frequencies_hz: elastic natural frequencies [Hz] (rigid modes dropped), with
    ``modes`` their 1-based mode numbers; speed_range_rad_s: (low, high) [rad/s];
    order_lines: DataFrame (order, speed_rad_s, speed_rpm, frequency_hz); crossings:
    DataFrame (order, mode, natural_frequency_hz, speed_rad_s, speed_rpm), one row per order
    line meeting a natural frequency inside the speed range, sorted by speed.
    """

    natural_frequencies_hz: np.ndarray
    modes: np.ndarray
    speed_range_rad_s: tuple
    orders: tuple
    order_lines: pd.DataFrame
    crossings: pd.DataFrame


def crossing_speed_rad_s(order: float, frequency_hz: float) -> float:
    """Speed [rad/s] at which engine order ``order`` has frequency ``frequency_hz`` [Hz]:
    k * speed / (2 pi) = f, i.e. rpm = 60 f / k."""
    return 2.0 * np.pi * float(frequency_hz) / float(order)


def campbell(natural_frequencies_hz, orders=DEFAULT_ORDERS, speed_range_rad_s=None, n_speeds: int = 51, modes=None) -> CampbellData:
    """Campbell data: order lines f = k * rpm / 60 against natural frequencies.

    Args:
        natural_frequencies_hz: natural frequencies [Hz] (a :class:`ModalResult` is accepted
            too: its elastic modes are used); zero or negative entries are ignored.
        orders: engine orders [-], default 1-8.
        speed_range_rad_s: (low, high) speed [rad/s]; default 500-3000 rpm.
        n_speeds: points per order line (the lines are straight; 2 would do for drawing).
        modes: 1-based mode numbers of the frequencies (default 1, 2, ...).

    Returns:
        :class:`CampbellData`; a crossing of order k with a mode f_n lies at speed
        2 pi f_n / k [rad/s] (60 f_n / k rpm) when that is inside the range.
    """
    if isinstance(natural_frequencies_hz, ModalResult):
        mr = natural_frequencies_hz
        keep = ~mr.rigid
        freqs = mr.frequencies_hz[keep]
        modes = np.flatnonzero(keep) + 1 if modes is None else modes
    else:
        freqs = np.atleast_1d(np.asarray(natural_frequencies_hz, dtype=float))
    if modes is None:
        modes = np.arange(1, freqs.size + 1)
    modes = np.asarray(modes)
    if modes.shape != freqs.shape:
        raise InputError(f"modes has {modes.size} entries for {freqs.size} natural frequencies")
    ok = np.isfinite(freqs) & (freqs > 0)
    freqs, modes = freqs[ok], modes[ok]
    k = np.atleast_1d(np.asarray(orders, dtype=float))
    if k.size == 0 or not np.all(np.isfinite(k) & (k > 0)):
        raise InputError(f"orders {orders!r}: accepted is one or more positive engine orders")
    if speed_range_rad_s is None:
        speed_range_rad_s = tuple(rpm_to_rad_s(np.asarray(DEFAULT_SPEED_RANGE_RPM)))
    lo, hi = (float(x) for x in speed_range_rad_s)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise InputError(f"speed range ({lo!r}, {hi!r}) rad/s: accepted is 0 < low < high")
    if not (isinstance(n_speeds, (int, np.integer)) and n_speeds >= 2):
        raise InputError(f"n_speeds {n_speeds!r}: accepted is a whole number >= 2")
    w = np.linspace(lo, hi, int(n_speeds))
    ww, kk = np.tile(w, k.size), np.repeat(k, w.size)
    lines = pd.DataFrame({"order": kk, "speed_rad_s": ww, "speed_rpm": rad_s_to_rpm(ww), "frequency_hz": kk * ww / (2 * np.pi)})
    rows = []
    for order in k:
        for m, f in zip(modes, freqs):
            s = crossing_speed_rad_s(order, f)
            if lo <= s <= hi:
                rows.append({"order": float(order), "mode": int(m), "natural_frequency_hz": float(f), "speed_rad_s": s, "speed_rpm": float(rad_s_to_rpm(s))})
    cross = pd.DataFrame(rows, columns=["order", "mode", "natural_frequency_hz", "speed_rad_s", "speed_rpm"])
    cross = cross.sort_values(["speed_rad_s", "order"]).reset_index(drop=True)
    return CampbellData(freqs, modes, (lo, hi), tuple(float(x) for x in k), lines, cross)


__all__ = [
    "ModalResult",
    "CampbellData",
    "dof_group",
    "modes_from_matrices",
    "modal_analysis",
    "crossing_speed_rad_s",
    "campbell",
]
