"""Engine full-load (WOT) mean-torque curve for torque-curve campaigns and map overlays.

In the thesis's torque-curve campaigns the rig's mean input torque at each speed point
followed the wide-open-throttle curve of the engine that is normally paired with this
damper ([thesis] §3.3.2): speed points from 1200 rpm (lowest speed with curve data) to
2800 rpm (rig limit), mean torques between about 240 and 415 N m (docs/model.md §7). The same
curve is drawn over the magnification maps to show the damper's usual operating region
([thesis] §6.3.1, §7.1.3).

The thesis does not tabulate the curve. :data:`DEFAULT_WOT_CURVE` is therefore **our
estimate of a typical 2.2 l four-cylinder diesel full-load curve**, shaped to the few facts
the thesis does give:

* 1200-2800 rpm, minimum about 240 N m (at 1200 rpm), maximum about 415 N m;
* the damper's outer knee (about 300 N m for the default parameter set) is crossed between
  1360 and 1380 rpm ([thesis] §6.2.1, Fig. 6.7): the estimate passes 300 N m at ~1370 rpm;
* a steep rise from 1200 rpm to a broad plateau near peak torque, then a gentle fall
  towards 2800 rpm, as usual for turbocharged diesels.

Use your engine's measured curve when you have one (:meth:`TorqueCurve.from_rpm`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError
from dampersim.units import rad_s_to_rpm, rpm_to_rad_s


@dataclass(frozen=True)
class TorqueCurve:
    """Piecewise-linear mean engine torque over speed.

    speeds_rad_s: strictly increasing speed points [rad/s] (at least two);
    torques_nm: mean torque at each point [N m]; name, source: description and origin.
    """

    speeds_rad_s: tuple
    torques_nm: tuple
    name: str = "torque curve"
    source: str = ""

    def __post_init__(self):
        try:
            w = np.asarray(self.speeds_rad_s, dtype=float)
            tq = np.asarray(self.torques_nm, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"torque curve {self.name!r}: speeds [rad/s] and torques [N m] must be numbers ({exc})") from None
        if w.ndim != 1 or tq.shape != w.shape or w.size < 2:
            raise InputError(
                f"torque curve {self.name!r}: accepted is two or more (speed, torque) points of equal "
                f"count, got {w.size} speeds and {tq.size} torques"
            )
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(tq))):
            raise InputError(f"torque curve {self.name!r}: speeds and torques must be finite numbers")
        if np.any(w <= 0) or np.any(np.diff(w) <= 0):
            raise InputError(
                f"torque curve {self.name!r}: speeds must be positive and strictly increasing, got "
                f"{np.round(rad_s_to_rpm(w), 1).tolist()} rpm"
            )
        object.__setattr__(self, "speeds_rad_s", tuple(float(x) for x in w))
        object.__setattr__(self, "torques_nm", tuple(float(x) for x in tq))

    @classmethod
    def from_rpm(cls, speeds_rpm, torques_nm, name="torque curve", source=""):
        """Build a curve from speed points in [rpm] and mean torques in [N m]."""
        try:
            w = rpm_to_rad_s(np.asarray(speeds_rpm, dtype=float))
        except (TypeError, ValueError) as exc:
            raise InputError(f"torque curve {name!r}: speeds must be numbers in rpm ({exc})") from None
        return cls(tuple(np.atleast_1d(w)), tuple(np.atleast_1d(np.asarray(torques_nm, dtype=float))), name, source)

    @property
    def speed_range_rad_s(self) -> tuple:
        """(lowest, highest) speed [rad/s] of the curve."""
        return self.speeds_rad_s[0], self.speeds_rad_s[-1]

    @property
    def speeds_rpm(self) -> np.ndarray:
        """Speed points [rpm]."""
        return rad_s_to_rpm(np.asarray(self.speeds_rad_s))

    def torque_at(self, speed_rad_s, extrapolate: bool = False):
        """Mean torque [N m] at ``speed_rad_s`` [rad/s] (scalar or array), linear between points.

        Speeds outside the curve raise :class:`InputError` (the curve says nothing there)
        unless ``extrapolate`` is true, in which case the end values are held.
        """
        try:
            w = np.asarray(speed_rad_s, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"speed {speed_rad_s!r}: accepted is a speed in rad/s (number or array)") from None
        if not np.all(np.isfinite(w)):
            raise InputError(f"speed {speed_rad_s!r}: accepted is a finite speed in rad/s")
        lo, hi = self.speed_range_rad_s
        # the curve's own end points must round-trip through rpm conversion: allow 1e-9 relative
        tol = 1e-9 * hi
        if not extrapolate and (np.any(w < lo - tol) or np.any(w > hi + tol)):
            bad = w[(w < lo - tol) | (w > hi + tol)].ravel()[0]
            raise InputError(
                f"speed {bad:.4g} rad/s ({rad_s_to_rpm(bad):.0f} rpm) lies outside the torque curve "
                f"{self.name!r}: accepted is {lo:.4g}-{hi:.4g} rad/s "
                f"({rad_s_to_rpm(lo):.0f}-{rad_s_to_rpm(hi):.0f} rpm)"
            )
        out = np.interp(w, np.asarray(self.speeds_rad_s), np.asarray(self.torques_nm))
        return float(out) if out.ndim == 0 else out

    def sample(self, n: int = 161):
        """``n`` evenly spaced speeds over the curve [rad/s] and their mean torques [N m]
        (161 points = the thesis's 10 rpm steps from 1200 to 2800 rpm)."""
        if not (isinstance(n, (int, np.integer)) and n >= 2):
            raise InputError(f"n = {n!r}: accepted is a whole number of points >= 2")
        lo, hi = self.speed_range_rad_s
        w = np.linspace(lo, hi, int(n))
        return w, self.torque_at(w)


#: Our estimate of a typical 2.2 l four-cylinder diesel WOT curve (see module docs).
_WOT_RPM = (1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900, 2000, 2200, 2400, 2600, 2800)
_WOT_NM = (240, 275, 310, 345, 375, 398, 410, 415, 415, 415, 410, 400, 385)

DEFAULT_WOT_CURVE = TorqueCurve.from_rpm(
    _WOT_RPM,
    _WOT_NM,
    name="typical diesel WOT (estimate)",
    source=(
        "estimate of a typical 2.2 l four-cylinder diesel full-load curve; range 1200-2800 rpm "
        "and 240-415 N m from [thesis] §3.3.2, 300 N m near 1370 rpm from [thesis] §6.2.1"
    ),
)


def default_torque_curve() -> TorqueCurve:
    """The default WOT mean-torque curve (an estimate; see module docs)."""
    return DEFAULT_WOT_CURVE


def torque_at(speed_rad_s, curve: TorqueCurve | None = None, extrapolate: bool = False):
    """Mean WOT torque [N m] at ``speed_rad_s`` [rad/s] on ``curve`` (default: the estimate).

    Raises :class:`InputError` for speeds outside the curve's range (1200-2800 rpm for the
    default) unless ``extrapolate``.
    """
    return (curve or DEFAULT_WOT_CURVE).torque_at(speed_rad_s, extrapolate=extrapolate)


__all__ = ["TorqueCurve", "DEFAULT_WOT_CURVE", "default_torque_curve", "torque_at"]
