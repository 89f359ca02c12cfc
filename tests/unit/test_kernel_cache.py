"""numba's on-disk cache of the kernels is keyed by the source they are compiled from.

numba's cache=True checks only the file of the function it loads: a changed constant in
an imported layout module, or a changed jitted helper in another module, would leave
stale machine code in use. dampersim.solver.numba_cache keys the cache of a guarded
package by the source of the whole package plus its layout modules. The toy package
below has the same shape as dampersim.solver.kernels (kernel -> helper module, kernel ->
constant of a layout module outside the package) and is run in fresh processes, with
and without the guard.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numba

import dampersim
from dampersim.keys import NUMBA_CODEGEN_ENV
from dampersim.solver import kernels, numba_cache

REPO = Path(dampersim.__file__).resolve().parent.parent

INIT = """\
import os
from pathlib import Path

if os.environ.get("TOY_GUARD") == "1":
    from dampersim.solver.numba_cache import guard

    _here = Path(__file__).resolve().parent
    guard(_here, (_here.parent / "toy_layout.py",))
"""
HELPER = """\
from numba import njit


@njit(cache=True)
def scale(x):
    return {factor} * x
"""
CALC = """\
from numba import njit

from toy_layout import K
from toykern.helper import scale


@njit(cache=True)
def f(x):
    return scale(x) + K
"""
RUN = "from toykern.calc import f; print(f(3.0), f.stats.cache_hits and 'hit' or 'miss')"


def _toy(root: Path) -> None:
    (root / "toykern").mkdir(parents=True)
    (root / "toykern" / "__init__.py").write_text(INIT)
    (root / "toykern" / "helper.py").write_text(HELPER.format(factor="2.0"))
    (root / "toykern" / "calc.py").write_text(CALC)
    (root / "toy_layout.py").write_text("K = 1.0\n")


def _run(root: Path, cache: Path, guard: bool, **settings) -> tuple[float, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_LOCATOR_CLASSES", *NUMBA_CODEGEN_ENV)}
    env.update(NUMBA_CACHE_DIR=str(cache), PYTHONDONTWRITEBYTECODE="1", TOY_GUARD="1" if guard else "0",
               PYTHONPATH=os.pathsep.join([str(root), str(REPO)]), **settings)
    out = subprocess.run([sys.executable, "-c", RUN], cwd=root, env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    value, how = out.stdout.split()
    return float(value), how


def test_changed_layout_constant_or_helper_recompiles(tmp_path):
    root, cache = tmp_path / "src", tmp_path / "numba"
    _toy(root)
    assert _run(root, cache, guard=True) == (7.0, "miss")  # 2 * 3 + 1
    assert _run(root, cache, guard=True) == (7.0, "hit")  # the cache is really used
    (root / "toy_layout.py").write_text("K = 5.0\n")  # a constant frozen into f
    assert _run(root, cache, guard=True) == (11.0, "miss")
    (root / "toykern" / "helper.py").write_text(HELPER.format(factor="3.0"))  # a helper f calls
    assert _run(root, cache, guard=True) == (14.0, "miss")
    # the entries live under NUMBA_CACHE_DIR, in one src-<key> folder per source version
    index = sorted(p.parent.name for p in cache.rglob("calc.f-*.nbi"))
    assert len(index) == 3 and all(name.startswith("src-") for name in index)


def test_without_the_guard_numba_serves_stale_code(tmp_path):
    # the control: what the guard prevents (numba 0.68 checks only calc.py itself)
    root, cache = tmp_path / "src", tmp_path / "numba"
    _toy(root)
    assert _run(root, cache, guard=False) == (7.0, "miss")
    (root / "toy_layout.py").write_text("K = 5.0\n")
    assert _run(root, cache, guard=False) == (7.0, "hit")  # stale: 11.0 is right


def test_another_optimisation_level_compiles_apart(tmp_path):
    # numba keys its cache by signature and CPU only: code compiled at level 3 is loaded under
    # NUMBA_OPT=1 (the control, unguarded), so a run that asks for other machine code (and, with
    # the kernels' reassociating fast-math, other last bits) silently gets the old one
    root, cache = tmp_path / "src", tmp_path / "numba"
    _toy(root)
    assert _run(root, cache, guard=False) == (7.0, "miss")
    assert _run(root, cache, guard=False, NUMBA_OPT="1") == (7.0, "hit")
    assert _run(root, cache, guard=True) == (7.0, "miss")
    assert _run(root, cache, guard=True, NUMBA_OPT="1") == (7.0, "miss")  # its own folder
    assert _run(root, cache, guard=True, NUMBA_OPT="1") == (7.0, "hit")
    assert _run(root, cache, guard=True, NUMBA_SLP_VECTORIZE="1") == (7.0, "miss")
    assert _run(root, cache, guard=True) == (7.0, "hit")  # the default's entry is still there
    # src-<key>-<settings>: one folder per setting, the same source key
    folders = {tuple(p.parent.name.split("-", 2)[1:]) for p in cache.rglob("calc.f-*.nbi")
               if p.parent.name.startswith("src-")}
    assert {tag for _, tag in folders} == {"O3-loop", "O1-loop", "O3-loop-slp"} and len({k for k, _ in folders}) == 1
    # at level 0 numba cannot cache the function (its code keeps dynamic globals) and says so
    # in a warning naming the source file, which the guarded locator must be able to give
    assert _run(root, cache, guard=True, NUMBA_OPT="0") == (7.0, "miss")


def test_every_kernel_is_cached_under_the_source_key():
    for name in ("fastmath", "springs", "contacts", "effects", "friction", "forces", "engine", "excitation", "integrate"):
        __import__(f"dampersim.solver.kernels.{name}")
    here = Path(kernels.__file__).resolve().parent
    key = numba_cache.source_key(here, (here.parent / "layout.py", here.parent / "engine_layout.py"))
    assert kernels.CACHE_KEY == key
    modules = [m for name, m in sorted(sys.modules.items()) if name.startswith("dampersim.solver.kernels.")]
    assert len(modules) >= 9
    found = 0
    for mod in modules:
        for obj in vars(mod).values():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj.__module__ == mod.__name__:
                path = Path(obj._cache.cache_path)
                assert path.name == f"src-{key[:20]}-{numba_cache.settings_tag()}", (mod.__name__, obj.__name__, path)
                if numba.config.CACHE_DIR:  # NUMBA_CACHE_DIR stays the root
                    assert str(path).startswith(os.path.abspath(numba.config.CACHE_DIR)), path
                found += 1
    assert found >= 30
