"""How the numba kernels of dampersim are compiled and cached: one module per topic.

Every kernel is compiled with :data:`JIT` (or :data:`LEAF`, for kernels that allocate
nothing). numba's on-disk cache of this package is keyed by the source of all its
modules plus the layout modules whose slot constants get frozen into the machine code
(:mod:`dampersim.solver.layout`, :mod:`dampersim.solver.engine_layout`); see
:mod:`dampersim.solver.numba_cache`. The key is registered here, before any module of
the package is imported (and so decorated).

Modules, lowest first: :mod:`.fastmath` (polynomial expm1/tanh/sin), :mod:`.springs`
(spring node coordinates), :mod:`.contacts` (hardstop contacts, coil stacking),
:mod:`.effects` (optional discrepancy effects), :mod:`.friction` (friction law and the
implicit friction solve), :mod:`.forces` (torques on every DOF, explicit right-hand side),
:mod:`.engine` (pulsation generator chain), :mod:`.excitation` (order-sum torque grid),
:mod:`.integrate` (the production step and the integration loop). Array layouts are
defined in :mod:`dampersim.solver.layout` and :mod:`dampersim.solver.engine_layout`; the
Python side calls the integrators only through :mod:`dampersim.solver.driver`.
"""

from pathlib import Path

from dampersim.solver import numba_cache

_HERE = Path(__file__).resolve().parent

#: source key of the compiled kernels (this package + the layout modules)
CACHE_KEY = numba_cache.guard(_HERE, (_HERE.parent / "layout.py", _HERE.parent / "engine_layout.py"))

# Compile options of every kernel: Python's division-by-zero checks are off (a check per
# division blocks SIMD code; a non-finite state is caught by the divergence check).
# Floating-point options: multiply-adds may fuse, sums may be reassociated (reductions
# over DOFs and contacts become SIMD code), the sign of a zero is not kept and a division
# may become a multiplication by the reciprocal. Each changes results only at rounding
# level; no NaN/inf assumption is made, so the divergence check still sees NaN. Measured
# 7 % off the step time against contraction alone (interleaved A/B runs in one process).
# The polynomial friction law keeps its accuracy under these options
# (tests/unit/test_friction_law.py).
# forceinline=False is numba's default, written out because numba hands a flag a kernel
# leaves unset down from the kernel being compiled when it calls it: without it, the
# kernels first compiled inside integrate.step (forceinline=True) would become
# always-inline, and their code would depend on which caller compiled them first.
JIT = dict(cache=True, error_model="numpy", fastmath={"contract", "reassoc", "nsz", "arcp"}, forceinline=False)
# Kernels that allocate nothing are compiled without numba's reference counting: the
# hot loop calls them every step, and each call would otherwise pay atomic
# increments and decrements on every array argument.
LEAF = dict(JIT, _nrt=False)
