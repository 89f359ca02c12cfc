"""Slot coordinates of every node of every arc spring ([thesis] Eq. 16-18).

The springs' torques on the bodies and masses are assembled in
:func:`dampersim.solver.kernels.forces.forces`; this module holds the node geometry
that forces, the elastic energy and the coil-stacking contact share.
"""

from numba import njit

from dampersim.solver.kernels import LEAF
from dampersim.solver.layout import F_PHIPS, F_PHISEG, F_PHISS, F_PITCH, I_A, I_N, I_NODE, I_OFF



@njit(**LEAF)
def spring_nodes(q, P, SF, SI, X):
    """Slot coordinates of every node of every spring into X (Eq. 16-18)."""
    for s in range(SF.shape[0]):
        a = SI[s, I_A]
        n = SI[s, I_N]
        off = SI[s, I_OFF]
        base = SI[s, I_NODE]
        w = q[a] - q[a + 1]
        phiseg = SF[s, F_PHISEG]
        pitch = SF[s, F_PITCH]
        qa = q[a]
        Xs = X[base:base + n + 1]  # views offset by the counter only (see forces)
        qm = q[off:off + n - 1]
        for i in range(n - 1):
            Xs[i + 1] = qa - qm[i]
        x0 = SF[s, F_PHIPS]
        xb = w + SF[s, F_PHISS]
        if xb > x0:
            x0 = xb
        xf = X[base + 1] - phiseg
        if xf > x0:
            x0 = xf
        X[base] = x0
        xn = pitch - SF[s, F_PHIPS]
        xb = w + pitch - SF[s, F_PHISS]
        if xb < xn:
            xn = xb
        xf = X[base + n - 1] + phiseg
        if xf < xn:
            xn = xf
        X[base + n] = xn
