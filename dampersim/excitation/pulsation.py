"""The motored-engine pulsation generator as a torque source ([thesis] chapter 4): its description and checks.

:class:`PulsationSource` says what drives the generator (nominal speed, charge pressure,
the mean torque set on its output) and how it starts up ([thesis] §6.2.1: the mean set
point ramps over ``mean_ramp`` s, the cylinder charge's effect over ``gas_ramp`` s);
:func:`check_speed_rpm` and :func:`pressure_warnings` judge a speed and a pressure
against the model's limits and the thesis's ranges. Running the generator, alone on its
stiff propshaft or coupled to the damper, is :func:`dampersim.simulation.simulate_pulsation`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace

import numpy as np

from dampersim.errors import InputError
from dampersim.parameters.engine import BAR, PRESSURE_THESIS_BAR, PulsationGenerator, check_pressure_bar, default_pulsation_generator
from dampersim.units import rad_s_to_rpm

#: Speeds the generator model accepts [rpm] and where the thesis ran it ([thesis] §3.3.2,
#: §7.1.3: the rig's dynamometers are limited to 3000 rpm; the model was validated up to it).
SPEED_LIMITS_RPM = (500.0, 4000.0)
SPEED_VALIDATED_RPM = (900.0, 3000.0)


def check_speed_rpm(rpm, warn=True) -> list:
    """Raise InputError outside SPEED_LIMITS_RPM; return warnings (and print them to
    stderr when ``warn``) outside the validated range."""
    lo, hi = SPEED_LIMITS_RPM
    try:
        r = float(rpm)
    except (TypeError, ValueError):
        r = float("nan")
    if not (math.isfinite(r) and lo <= r <= hi):
        raise InputError(f"speed {rpm!r} rpm: accepted is {lo:g} to {hi:g} rpm for the pulsation generator model")
    out = []
    vlo, vhi = SPEED_VALIDATED_RPM
    if not vlo <= r <= vhi:
        out.append(f"warning: {r:g} rpm lies outside {vlo:g}-{vhi:g} rpm, where the thesis validated the model")
    if warn:
        for w in out:
            print(w, file=sys.stderr)
    return out


def pressure_warnings(pressure_bar) -> list:
    lo, hi = PRESSURE_THESIS_BAR
    if not lo <= pressure_bar <= hi:
        return [f"warning: {pressure_bar:g} bar lies outside the {lo:g}-{hi:g} bar the thesis used"]
    return []


@dataclass(frozen=True)
class PulsationSource:
    """The pulsation generator driven at nominal ``speed`` [rad/s].

    pressure_bar: charge pressure P_c [bar abs] (0.5-4; the thesis used 1-3);
    mean_torque: mean torque set on the generator's output [N m] (the input dyno's
    integral control holds it, [thesis] §4.3.1); generator: its parameters (default
    :func:`default_pulsation_generator`); start-up as the thesis's (§6.2.1): the mean set
    point ramps over ``mean_ramp`` s, the cylinder charge's effect over ``gas_ramp`` s.
    Checked on construction (InputError / ParameterError naming the accepted range).
    """

    speed: float
    pressure_bar: float = 2.5
    mean_torque: float = 200.0
    generator: PulsationGenerator | None = None
    mean_ramp: float = 0.3
    gas_ramp: float = 0.3

    def __post_init__(self):
        speed = self.speed
        if not (math.isfinite(speed) and speed > 0):
            raise InputError(f"speed = {speed!r} rad/s: accepted is a positive speed")
        check_speed_rpm(rad_s_to_rpm(speed), warn=False)
        object.__setattr__(self, "pressure_bar", check_pressure_bar(self.pressure_bar))
        mean_torque = self.mean_torque
        if not (math.isfinite(mean_torque) and abs(mean_torque) <= 1000.0):
            raise InputError(f"mean torque {mean_torque!r} N m: accepted is within +-1000 N m")

    @property
    def steady_start(self) -> float:
        """Time [s] from which set point and charge are steady."""
        return self.mean_ramp + self.gas_ramp

    @property
    def charge_pressure(self) -> float:
        """P_c [Pa abs]."""
        return self.pressure_bar * BAR

    def charged_generator(self) -> PulsationGenerator:
        """The generator's parameters with this source's charge pressure."""
        pg = self.generator if self.generator is not None else default_pulsation_generator()
        return replace(pg, charge_pressure=self.charge_pressure)

    def setpoint(self, t: np.ndarray) -> np.ndarray:
        """Mean torque set point [N m] at times t [s] (ramped over ``mean_ramp``)."""
        if self.mean_ramp > 0:
            return self.mean_torque * np.clip(t / self.mean_ramp, 0.0, 1.0)
        return np.full(len(t), self.mean_torque)

    def gas_scale(self, t: np.ndarray) -> np.ndarray:
        """Factor on the gas pressure above atmosphere [-] at times t [s] (ramped over
        ``gas_ramp`` after the mean torque's ramp)."""
        if self.gas_ramp > 0:
            return np.clip((t - self.mean_ramp) / self.gas_ramp, 0.0, 1.0)
        return np.ones(len(t))


__all__ = [
    "SPEED_LIMITS_RPM",
    "SPEED_VALIDATED_RPM",
    "PulsationSource",
    "check_speed_rpm",
    "pressure_warnings",
]
