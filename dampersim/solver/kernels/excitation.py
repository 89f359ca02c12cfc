"""The engine-order input torque on the integrator's step grid, in one compiled pass.

The solver builds the grid from the description an excitation hands it (orders,
amplitudes, phases, ramps: :meth:`dampersim.excitation.OrderSum.order_spec`) through
:func:`dampersim.solver.driver.torque_grid`.
"""

import math

from numba import njit

from dampersim.solver.kernels import LEAF

ORDER_SUM_RESYNC = 32  # samples between exact cos/sin evaluations in order_sum


@njit(**LEAF)
def order_sum(out, dt, speed, mean, mean_ramp, amplitude_ramp, K, A, PH):
    """T_in(n dt) for n = 0 .. len(out)-1 into ``out`` [N m]: the order sum of
    :class:`dampersim.excitation.OrderSum` (docs/model.md §7, [thesis] §6.2.1) on the
    integrator's grid. speed [rad/s], mean [N m], ramps [s]; order k (K[k] [-]) has
    amplitude A[k] [N m] and phase PH[k] [rad].

    Each order's cosine advances by a rotation through k speed dt, with an exact cos/sin
    every ORDER_SUM_RESYNC samples, so rounding cannot accumulate beyond a few dozen ulp
    (tested against the NumPy form); one pass over the grid instead of a cosine call per
    order and sample."""
    n = out.shape[0]
    for i in range(n):
        t = i * dt
        m = 1.0 if mean_ramp <= 0.0 else min(t / mean_ramp, 1.0)
        out[i] = mean * m
    for k in range(K.shape[0]):
        w = K[k] * speed
        cd = math.cos(w * dt)
        sd = math.sin(w * dt)
        a = A[k]
        i0 = 0
        while i0 < n:
            ph = w * (i0 * dt) + PH[k]
            c = math.cos(ph)
            s = math.sin(ph)
            i1 = min(i0 + ORDER_SUM_RESYNC, n)
            for i in range(i0, i1):
                t = i * dt
                if amplitude_ramp > 0.0:
                    env = min(max((t - mean_ramp) / amplitude_ramp, 0.0), 1.0)
                else:
                    env = 1.0 if t >= mean_ramp else 0.0
                out[i] += env * a * c
                c, s = c * cd - s * sd, s * cd + c * sd
            i0 = i1
