"""SimulationResult: SI time series of one run, with helpers for analysis and export."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dampersim.solver import _kernels as kern
from dampersim.solver.layout import Layout

ANALYSIS_WINDOW = 1.25  # s, [thesis] §3.4 and §6.2.1


def _transducer(tout, system, rec_dt):
    """Output torque as the transducer reports it: unchanged, or with effect
    transducer_bandwidth a causal first-order low pass at its cutoff [Hz]."""
    tb = getattr(getattr(system, "effects", None), "transducer_bandwidth", None)
    if tb is None or not tb.enabled or len(tout) < 2:
        return tout
    from dampersim.signal import lowpass_first_order

    return lowpass_first_order(tout, 1.0 / rec_dt, tb.cutoff)


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Time series of a simulation (SI units).

    t [s]; input_torque, output_torque [N m] (torque entering J_pri; shaft torque at the
    output transducer, [thesis] §6.2.1); speed_* [rad/s] absolute; windup_outer,
    windup_inner [rad] (windup of each set), windup_total [rad] (J_pri minus output
    transducer angle, the rig's measured windup); hardstop_outer/inner [N m] (contact
    torque, 0 when free); energy: dict of cumulative energies [J].
    Segment states: segment_t [s], nodes [frames, nodes] slot coordinates [rad].
    """

    t: np.ndarray
    input_torque: np.ndarray
    output_torque: np.ndarray
    speed_primary: np.ndarray
    speed_secondary: np.ndarray
    speed_tertiary: np.ndarray
    speed_motor: np.ndarray
    windup_outer: np.ndarray
    windup_inner: np.ndarray
    windup_total: np.ndarray
    hardstop_outer: np.ndarray
    hardstop_inner: np.ndarray
    motor_torque: np.ndarray
    spring_torque_outer: np.ndarray
    spring_torque_inner: np.ndarray
    energy: dict
    segment_t: np.ndarray
    nodes: np.ndarray
    springs: tuple
    spring_rows: np.ndarray = field(repr=False)
    speed: float = 0.0
    time_step: float = 0.0
    sample_rate: float = 0.0
    steady_start: float = 0.0
    wall_time: float = 0.0
    parameters: object = field(default=None, repr=False)
    excitation: object = field(default=None, repr=False)

    @classmethod
    def from_records(cls, rec, seg, layout: Layout, system, excitation, dt, rec_dt, seg_dt, wall_time):
        c = rec.T
        energy = {
            "input_work": c[kern.R_E_IN].copy(),
            "motor_work": c[kern.R_E_MOTOR].copy(),
            "kinetic": c[kern.R_E_KIN].copy(),
            "elastic": c[kern.R_E_SPRING].copy(),
            "friction": c[kern.R_E_FRIC].copy(),
            "damping": c[kern.R_E_DAMP].copy(),
            "stacking": c[kern.R_E_STACK].copy(),
        }
        return cls(
            t=c[kern.R_T].copy(),
            input_torque=c[kern.R_TIN].copy(),
            output_torque=_transducer(c[kern.R_TOUT].copy(), system, rec_dt),
            speed_primary=c[kern.R_W_PRI].copy(),
            speed_secondary=c[kern.R_W_SEC].copy(),
            speed_tertiary=c[kern.R_W_TER].copy(),
            speed_motor=c[kern.R_W_MOTOR].copy(),
            windup_outer=c[kern.R_WIND_O].copy(),
            windup_inner=c[kern.R_WIND_I].copy(),
            windup_total=c[kern.R_WIND_RIG].copy(),
            hardstop_outer=c[kern.R_HS_O].copy(),
            hardstop_inner=c[kern.R_HS_I].copy(),
            motor_torque=c[kern.R_MOTOR_T].copy(),
            spring_torque_outer=c[kern.R_SET_O].copy(),
            spring_torque_inner=c[kern.R_SET_I].copy(),
            energy=energy,
            segment_t=np.arange(seg.shape[0]) * seg_dt,
            nodes=seg,
            springs=layout.springs,
            spring_rows=layout.SF.copy(),
            speed=float(excitation.speed),
            time_step=dt,
            sample_rate=1.0 / rec_dt,
            steady_start=float(getattr(excitation, "steady_start", 0.0)),
            wall_time=wall_time,
            parameters=system,
            excitation=excitation,
        )

    # --- analysis helpers ------------------------------------------------------------
    def window(self, seconds: float = ANALYSIS_WINDOW) -> slice:
        """Slice of the last ``seconds`` [s] of the stored series (the analysis window)."""
        n = int(round(seconds * self.sample_rate))
        n = min(n, len(self.t))
        return slice(len(self.t) - n, len(self.t))

    def order_amplitudes(self, orders=tuple(range(1, 9)), seconds: float = ANALYSIS_WINDOW):
        """(input, output) order amplitudes [N m] over the analysis window ([thesis] §3.4)."""
        from dampersim.signal import order_amplitudes

        w = self.window(seconds)
        a_in = order_amplitudes(self.input_torque[w], self.sample_rate, self.speed, orders)
        a_out = order_amplitudes(self.output_torque[w], self.sample_rate, self.speed, orders)
        return a_in, a_out

    def energy_residual(self) -> np.ndarray:
        """Work of external torques minus (change of stored energy + dissipation) [J]."""
        e = self.energy
        stored = (e["kinetic"] - e["kinetic"][0]) + (e["elastic"] - e["elastic"][0])
        return e["input_work"] + e["motor_work"] - stored - e["friction"] - e["damping"] - e["stacking"]

    def spring_nodes(self, name: str) -> np.ndarray:
        """Slot coordinates [rad] of one spring's N+1 nodes over the segment frames."""
        for sp in self.springs:
            if sp.name == name:
                return self.nodes[:, sp.first_node:sp.first_node + sp.segments + 1]
        raise KeyError(f"spring {name!r}: accepted is one of {[s.name for s in self.springs]}")

    def segment_compression(self, name: str) -> np.ndarray:
        """Compression [rad] of each segment of spring ``name`` (relaxed arc minus arc)."""
        x = self.spring_nodes(name)
        k = [s.name for s in self.springs].index(name)
        from dampersim.solver.layout import F_PHISEG

        return self.spring_rows[k, F_PHISEG] - np.diff(x, axis=1)

    def to_frame(self):
        """pandas DataFrame of the stored time series (SI column names with units)."""
        import pandas as pd

        return pd.DataFrame(
            {
                "time_s": self.t,
                "input_torque_nm": self.input_torque,
                "output_torque_nm": self.output_torque,
                "speed_primary_rad_s": self.speed_primary,
                "speed_secondary_rad_s": self.speed_secondary,
                "speed_tertiary_rad_s": self.speed_tertiary,
                "speed_motor_rad_s": self.speed_motor,
                "windup_outer_rad": self.windup_outer,
                "windup_inner_rad": self.windup_inner,
                "windup_total_rad": self.windup_total,
                "hardstop_outer_nm": self.hardstop_outer,
                "hardstop_inner_nm": self.hardstop_inner,
                "motor_torque_nm": self.motor_torque,
            }
        )
