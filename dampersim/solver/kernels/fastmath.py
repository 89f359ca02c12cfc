"""Fast, branch-free elementary functions for the kernels: expm1, tanh and a short sine.

Only multiplications and additions, so loops over many contacts or segments that call
them compile to SIMD code (libm's exp and sin are opaque calls); each keeps a relative
accuracy of a few ulp over the range its callers use (tests/unit/test_friction_law.py).
"""

import math

from numba import njit

from dampersim.solver.kernels import JIT

# Taylor coefficients 1/k! of expm1, k = 1..12
_C2, _C3, _C4, _C5, _C6, _C7 = 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040
_C8, _C9, _C10, _C11, _C12 = 1.0 / 40320, 1.0 / 362880, 1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600


@njit(inline="always", **JIT)
def expm1_neg(y):
    """exp(-y) - 1 for y >= 0, accurate to a few ulp relative, branch-free.

    y is clamped at 40 (exp(-40) is below float64's resolution next to 1), scaled by
    2^-7 into [0, 0.3125], where a degree-12 Taylor polynomial has truncation error
    < 2e-16 relative; seven doublings e^(2h) - 1 = u (2 + u) bring it back. A doubling
    never amplifies the relative error for u in (-1, 0], and no step cancels, so the
    result stays accurate near y = 0 (unlike 1 - exp(-y)). Only multiplications and
    additions: loops over many contacts vectorise (libm's exp is an opaque call)."""
    h = -min(y, 40.0) * (1.0 / 128.0)
    u = h * (1.0 + h * (_C2 + h * (_C3 + h * (_C4 + h * (_C5 + h * (_C6 + h * (_C7 + h * (
        _C8 + h * (_C9 + h * (_C10 + h * (_C11 + h * _C12)))))))))))
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    return u


@njit(inline="always", **JIT)
def fast_tanh(x):
    """tanh(x) = -u / (2 + u) with u = expm1(-2|x|): relative error of a few ulp for
    every x (no cancellation near 0), exactly +-1 where tanh rounds to +-1."""
    u = expm1_neg(2.0 * abs(x))
    return math.copysign(-u / (2.0 + u), x)


@njit(inline="always", **JIT)
def sin_poly(x):
    """sin(x) for |x| <= 0.5 (error < 1e-12 relative) as a short odd polynomial, without
    branches; callers check the range. The redirection angle of a segment per coil is a
    few hundredths of a radian."""
    x2 = x * x
    # Taylor series in nested form, divisions by constants written as products
    return x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0) * (
        1.0 - x2 * (1.0 / 72.0) * (1.0 - x2 * (1.0 / 110.0))))))
