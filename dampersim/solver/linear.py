"""Linearised model: frictionless, hardstops ignored, about the unloaded state.

The springs are taken in the positive-torque contact configuration of [thesis] Eq. 8-11
(node 1 of each spring on the stopper of the body after the set, node N+1 on the body
before it), which is the configuration any positive mean torque produces. The matrices
are assembled from the spring segments and rig shafts directly (not by differencing the
kernel), so they are an independent check of the kernel. The short inner spring of
effect inner_short_springs has a clearance in that state and carries no torque: only its
inner segments are assembled.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from dampersim.errors import AccuracyWarning, InputError, ParameterError
from dampersim.parameters.model import DamperSystem, Solver
from dampersim.solver.layout import F_COUNT, F_KSEG, I_A, I_N, I_OFF, P_MOTOR, P_PA_C, P_PA_DOF, P_PA_K, P_RIG0, P_TD_C, build_layout


@dataclass(frozen=True)
class LinearModel:
    """M q'' + C q' + K q = f. SI units: kg m^2, N m s/rad, N m/rad."""

    dof_names: tuple
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    input_dof: int
    output_shaft_dofs: tuple  # (dof before the transducer shaft, transducer dof)
    output_shaft_k: float
    output_shaft_c: float
    motor: str  # "free" or "held"

    def natural_frequencies_hz(self) -> np.ndarray:
        """Undamped natural frequencies [Hz], ascending (rigid-body modes give 0)."""
        lam = np.linalg.eigvals(np.linalg.solve(self.M, self.K))
        lam = np.sort(np.abs(lam.real))
        return np.sqrt(lam) / (2 * np.pi)

    def mode_shapes(self):
        """(frequencies [Hz], shapes[:, k] normalised to unit max modulus)."""
        lam, vec = np.linalg.eig(np.linalg.solve(self.M, self.K))
        order = np.argsort(np.abs(lam.real))
        lam, vec = np.abs(lam.real[order]), vec[:, order].real
        vec = vec / np.max(np.abs(vec), axis=0)
        return np.sqrt(lam) / (2 * np.pi), vec

    def output_torque_response(self, omega: float) -> complex:
        """Complex output-transducer torque per unit input torque at omega [rad/s]."""
        n = len(self.dof_names)
        f = np.zeros(n, dtype=complex)
        f[self.input_dof] = 1.0
        z = -omega**2 * self.M + 1j * omega * self.C + self.K
        x = np.linalg.solve(z, f)
        a, b = self.output_shaft_dofs
        xa = x[a] if a >= 0 else 0.0
        return (self.output_shaft_k + 1j * omega * self.output_shaft_c) * (xa - x[b])

    def to_dict(self) -> dict:
        return {
            "dof_names": list(self.dof_names),
            "M": self.M.tolist(),
            "C": self.C.tolist(),
            "K": self.K.tolist(),
            "input_dof": self.input_dof,
            "output_shaft": {
                "dofs": [self.dof_names[d] for d in self.output_shaft_dofs],
                "k": self.output_shaft_k,
                "c": self.output_shaft_c,
            },
            "motor": self.motor,
            "natural_frequencies_hz": self.natural_frequencies_hz().tolist(),
        }


def _assemble(system: DamperSystem, hardstop_stiffness: float = 0.0, omega0: float = 100.0,
              short_engaged: bool = False):
    """Layout, M, C, K. The short inner spring of effect inner_short_springs has a
    clearance at zero windup (docs/model.md §4): its end segments are left out, so its
    chain of masses floats (a zero-frequency mode), unless ``short_engaged`` (the
    stability bound takes every spring engaged, like the hardstops)."""
    import dataclasses

    if system.effects.clutch_slip.enabled:  # linearised with the lock-up clutch closed
        eff = dataclasses.replace(system.effects, clutch_slip=dataclasses.replace(system.effects.clutch_slip, enabled=False))
        system = dataclasses.replace(system, effects=eff)
    lay = build_layout(system, omega0)
    n = lay.ndof
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    for s in range(len(lay.SF)):
        a = int(lay.SI[s, I_A])
        b = a + 1
        nseg = int(lay.SI[s, I_N])
        off = int(lay.SI[s, I_OFF])
        kk = lay.SF[s, F_COUNT] * lay.SF[s, F_KSEG]
        free_ends = lay.springs[s].name == "short_pair_inner" and not short_engaged
        # gradient of node slot coordinate x: mass x = q_A - q_m; node 0 x = q_A - q_B + c;
        # node N x = constant (on A's stopper)
        def grad(node):
            g = np.zeros(n)
            if node == 0:
                g[a] += 1.0
                g[b] -= 1.0
            elif node < nseg:
                g[a] += 1.0
                g[off + node - 1] -= 1.0
            return g

        for j in range(nseg):
            if free_ends and j in (0, nseg - 1):
                continue
            g = grad(j + 1) - grad(j)
            K += kk * np.outer(g, g)
    rig0 = int(lay.P[P_RIG0])
    for e in range(len(lay.rig)):
        d = rig0 + e
        p = 2 if e == 0 else d - 1
        for mat, val in ((K, lay.rig[e, 0]), (C, lay.rig[e, 1])):
            mat[p, p] += val
            mat[d, d] += val
            mat[p, d] -= val
            mat[d, p] -= val
        C[d, d] += lay.rig[e, 2]
    # effects: pendulum absorber (tuned at omega0), turbine drag
    pa = int(lay.P[P_PA_DOF])
    pairs = [(1, pa, lay.P[P_PA_K], lay.P[P_PA_C])] if pa >= 0 else []
    pairs.append((0, 1, 0.0, lay.P[P_TD_C]))
    for p, d, kk, cc in pairs:
        for mat, val in ((K, kk), (C, cc)):
            mat[p, p] += val
            mat[d, d] += val
            mat[p, d] -= val
            mat[d, p] -= val
    if hardstop_stiffness > 0:
        for a in (0, 1):
            K[a, a] += hardstop_stiffness
            K[a + 1, a + 1] += hardstop_stiffness
            K[a, a + 1] -= hardstop_stiffness
            K[a + 1, a] -= hardstop_stiffness
    return lay, np.diag(lay.J), C, K


def linearise(system: DamperSystem, motor: str = "free") -> LinearModel:
    """Export M, C, K of ``system``; ``motor`` 'free' (no speed control) or 'held'
    (the output motor DOF removed: its shaft ends on ground)."""
    if motor not in ("free", "held"):
        raise InputError(f"output motor = {motor!r}: accepted is 'free' or 'held'")
    lay, M, C, K = _assemble(system)
    names = list(lay.dof_names)
    trans = names.index(system.rig.output_transducer)
    e = lay.rig_names.index(system.rig.output_transducer)
    prev = 2 if e == 0 else trans - 1
    if motor == "held":
        mdof = int(lay.P[P_MOTOR])
        keep = np.array([i for i in range(len(names)) if i != mdof])
        M, C, K = M[np.ix_(keep, keep)], C[np.ix_(keep, keep)], K[np.ix_(keep, keep)]
        names = [names[i] for i in keep]
    return LinearModel(
        dof_names=tuple(names),
        M=M,
        C=C,
        K=K,
        input_dof=0,
        output_shaft_dofs=(prev, trans),
        output_shaft_k=float(lay.rig[e, 0]),
        output_shaft_c=float(lay.rig[e, 1]),
        motor=motor,
    )


def max_stable_time_step(system: DamperSystem) -> float:
    """Largest time step [s] we accept for ``system``.

    Symplectic Euler is stable for omega*dt < 2 on the stiffest mode; we keep a margin
    (omega_max * dt <= 1.5) with the hardstop contact stiffness engaged on both sets,
    and require explicit viscous terms to stay well damped (c/J * dt <= 1). The hardstop
    contact damping is integrated implicitly and sets no bound.
    """
    lay, M, C, K = _assemble(system, system.hardstops.stiffness if system.hardstops.enabled else 0.0,
                             short_engaged=True)
    jinv = 1.0 / np.diag(M)
    lam = np.linalg.eigvals(K * np.sqrt(jinv)[:, None] * np.sqrt(jinv)[None, :])
    wmax = float(np.sqrt(np.max(np.abs(lam.real))))
    cmax = float(np.max(np.abs(np.diag(C)) * jinv))
    dt = 1.5 / wmax
    if cmax > 0:
        dt = min(dt, 1.0 / cmax)
    return dt


def accuracy_tested_time_step() -> float:
    """The largest time step [s] whose accuracy the accuracy grid checks: the default
    ``solver.time_step`` (docs/model.md §12, ``python bench/bench_accuracy.py --grid step``)."""
    return next(f.default for f in dataclasses.fields(Solver) if f.name == "time_step")


def check_time_step(system: DamperSystem) -> DamperSystem:
    """Raise ParameterError naming ``solver.time_step`` when the step [s] exceeds
    :func:`max_stable_time_step` of this parameter set; return ``system`` otherwise.
    A stable step above :func:`accuracy_tested_time_step` is allowed with an
    :class:`~dampersim.errors.AccuracyWarning`.

    The bound depends on the discretisation (segment counts, contact stiffness), so it is
    the solver's check, made after :func:`dampersim.parameters.validate`.
    """
    note = time_step_note(system)
    if note:
        warnings.warn(note, AccuracyWarning, stacklevel=2)
    return system


def time_step_note(system: DamperSystem) -> str:
    """Raise ParameterError naming ``solver.time_step`` when the step [s] exceeds
    :func:`max_stable_time_step`; otherwise the text of the accuracy warning when it
    exceeds :func:`accuracy_tested_time_step`, or "" (the dashboard shows the text as a
    notice without going through the process-wide ``warnings`` state)."""
    dt = system.solver.time_step
    dt_max = max_stable_time_step(system)
    if dt > dt_max:
        raise ParameterError(
            "solver.time_step",
            dt,
            f"a step at or below the stability bound {dt_max:.3g} s of this parameter set",
        )
    tested = accuracy_tested_time_step()
    if dt > tested * (1.0 + 1e-9):
        return (f"solver.time_step = {dt:.4g} s is stable (bound {dt_max:.3g} s) but above {tested:.4g} s, the "
                "largest step whose accuracy is checked (docs/model.md §12): results may carry larger errors")
    return ""
