"""Cache keys: source hashes follow the imports, so a changed module changes the key."""

import json
import math
import mmap
import os
import platform
import shutil
import subprocess
import sys

import numpy as np
import pytest

from dampersim import keys
from dampersim.errors import InputError
from dampersim.sweeps import cache as sc

RECORD = sc.RECORD_MODULE


@pytest.fixture
def package_copy(tmp_path):
    """A copy of the dampersim sources to edit (caches and compiled files left out)."""
    dst = tmp_path / "dampersim"
    shutil.copytree(keys.PACKAGE_DIR, dst, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc"))
    return dst


def test_copy_hashes_like_the_package(package_copy):
    assert keys.source_hash_at(RECORD, package_copy) == keys.source_hash(RECORD)


def test_changed_source_of_a_reached_module_changes_the_key(package_copy):
    before = keys.source_hash_at(RECORD, package_copy)
    # the transducer low pass sits in signal.py; sweep points reach it through results.py
    path = package_copy / "signal.py"
    path.write_text(path.read_text().replace("LOWPASS_CUTOFF_HZ = 10.0", "LOWPASS_CUTOFF_HZ = 10.5"))
    assert keys.source_hash_at(RECORD, package_copy) != before


def test_a_new_module_is_covered_once_something_imports_it(package_copy):
    before = keys.source_hash_at(RECORD, package_copy)
    (package_copy / "solver" / "extra_law.py").write_text("GAIN = 2.0\n")
    assert keys.source_hash_at(RECORD, package_copy) == before  # nothing imports it yet
    layout = package_copy / "solver" / "layout.py"
    layout.write_text(layout.read_text() + "\nfrom dampersim.solver.extra_law import GAIN  # noqa: E402\n")
    with_import = keys.source_hash_at(RECORD, package_copy)
    assert with_import != before
    (package_copy / "solver" / "extra_law.py").write_text("GAIN = 3.0\n")
    assert keys.source_hash_at(RECORD, package_copy) != with_import


def test_imports_inside_functions_and_relative_imports_are_followed(package_copy):
    (package_copy / "probe.py").write_text("def f():\n    from . import units\n    from .signal import order_amplitudes\n")
    closure = keys.module_closure("dampersim.probe", package_copy)
    assert "dampersim.units" in closure and "dampersim.signal" in closure


def test_a_module_the_result_does_not_reach_leaves_the_key_alone(package_copy):
    before = keys.source_hash_at(RECORD, package_copy)
    plotting = package_copy / "plotting" / "theme.py"
    assert "dampersim.plotting.theme" not in keys.module_closure(RECORD, package_copy)
    plotting.write_text(plotting.read_text() + "\n# a comment\n")
    assert keys.source_hash_at(RECORD, package_copy) == before


def test_canonical_form_is_exact_and_refuses_unknown_values():
    assert keys.canonical(0.1) == {"f": (0.1).hex()}
    assert keys.digest({"x": 1.0}) != keys.digest({"x": math.nextafter(1.0, 2.0)})
    a = np.arange(4.0)
    assert keys.digest({"a": a}) == keys.digest({"a": a.copy()}) != keys.digest({"a": a[::-1].copy()})
    with pytest.raises(InputError, match="cache key"):
        keys.canonical(object())


def test_platform_names_the_libraries_and_cpu_that_shape_numbers():
    plat = keys.platform()
    for name in ("numpy", "numba", "llvmlite", "python", "cpu"):
        assert plat[name]
    doc = keys.key_document("probe", RECORD, {"x": 1})
    assert doc["platform"] == plat and doc["source"] == keys.source_hash(RECORD)


def test_platform_names_the_target_numba_was_told_to_compile_for(monkeypatch):
    # NUMBA_CPU_NAME / NUMBA_CPU_FEATURES (read into numba's config at import) change the
    # machine code and so a chaotic run's numbers: a result computed for another target is
    # not this one's
    from numba.core import config

    host = keys.platform.__wrapped__()["cpu"]
    monkeypatch.setattr(config, "CPU_NAME", "generic")
    monkeypatch.setattr(config, "CPU_FEATURES", "")
    assert keys.platform.__wrapped__()["cpu"] == {"name": "generic", "features": ""} != host
    monkeypatch.setattr(config, "CPU_NAME", None)
    monkeypatch.setattr(config, "CPU_FEATURES", "+sse2")  # features alone: the host's name
    assert keys.platform.__wrapped__()["cpu"] == {"name": host["name"], "features": "+sse2"}
    monkeypatch.setattr(config, "CPU_FEATURES", None)
    monkeypatch.setattr(config, "ENABLE_AVX", False)  # numba then drops AVX from the host's features
    assert keys.platform.__wrapped__()["cpu"]["features"] != host["features"] or "+avx" not in host["features"]


def test_platform_names_numba_s_code_generation_settings():
    # NUMBA_OPT=1 against the default 3 moved a 1500 rpm, 150 N m fired-engine run's total
    # windup by up to 1.2e-3 rad (of 0.49 rad) at 25 908 of its 26 000 samples (thesis
    # segments, numba 0.68.1): a result computed at another level is not this one's. "max" is
    # level 3 with an extra pass (other machine code), not 3. numba's config reads the
    # settings at import, so each is set in a fresh process
    code = ("import json, dampersim.keys as k; "
            "print(json.dumps([k.platform()['numba_codegen'], k.make_key('p', 'x', {})]))")
    def run(**env):
        base = {k: v for k, v in os.environ.items() if k not in keys.NUMBA_CODEGEN_ENV}
        out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                             check=True)
        return json.loads(out.stdout)

    default, key = run()
    assert default == {"opt": 3, "disable_jit": False, "loop_vectorize": True, "slp_vectorize": False}
    seen = {key}
    for name, value, field, read in (("NUMBA_OPT", "1", "opt", 1), ("NUMBA_OPT", "max", "opt", "max"),
                                     ("NUMBA_LOOP_VECTORIZE", "0", "loop_vectorize", False),
                                     ("NUMBA_SLP_VECTORIZE", "1", "slp_vectorize", True),
                                     ("NUMBA_DISABLE_JIT", "1", "disable_jit", True)):
        settings, other = run(**{name: value})
        assert settings == {**default, field: read}, name
        seen.add(other)
    assert len(seen) == 6  # each setting keys apart


@pytest.mark.skipif(sys.platform != "linux" or platform.machine() != "x86_64",
                    reason="the OpenBLAS kernel names and numpy's X86_V3 group are those of x86-64 Linux wheels")
def test_platform_names_the_blas_kernel_and_numpy_s_features():
    # the diagnosis's path moves with the BLAS kernel's rounding and numpy's dispatch
    # (docs/discrepancy.md, Known limits): both are read in a fresh process, as set at start
    code = "import json, dampersim.keys as k; p = k.platform(); print(json.dumps([p['blas'], p['numpy_cpu']]))"

    def run(**env):
        base = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES")}
        out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                             check=True)
        return json.loads(out.stdout)

    host_blas, host_cpu = run()
    blas, cpu = run(OPENBLAS_CORETYPE="Sandybridge", NPY_DISABLE_CPU_FEATURES="X86_V3")
    assert host_blas and set(blas) == set(host_blas) and set(blas.values()) == {"Sandybridge"}
    assert "X86_V3" not in cpu and set(cpu) <= set(host_cpu)


@pytest.mark.skipif(sys.platform != "linux", reason="/proc/self/maps is Linux's")
def test_the_blas_probe_reads_odd_mapped_file_names(tmp_path):
    # any file mapped into the process (a memmap, a database) is listed with its name, which
    # need not be UTF-8 and may hold spaces: the probe must still find the kernels
    odd = os.path.join(os.fsencode(tmp_path), "a caf\xe9 file".encode("latin-1"))
    with open(odd, "wb") as fh:
        fh.write(b"\0" * 4096)
    with open(odd, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ):
        kernels = keys.blas_kernels()
    assert "error" not in kernels, kernels
    assert kernels == keys.platform()["blas"]


def test_view_keys_cover_figures_analysis_and_the_diagnosis():
    explorer = keys.module_closure("dampersim.views.explorer")
    for name in ("dampersim.plotting.traces", "dampersim.plotting.spectra", "dampersim.analysis.order_table",
                 "dampersim.signal", "dampersim.solver.kernels.integrate", "dampersim.views.store"):
        assert name in explorer, name
    diagnosis = keys.module_closure("dampersim.views.discrepancy")
    for name in ("dampersim.discrepancy.diagnose", "dampersim.discrepancy.report", "dampersim.discrepancy.drive",
                 "dampersim.plotting.discrepancy", "dampersim.solver.kernels.effects"):
        assert name in diagnosis, name


def test_another_page_edited_leaves_a_cached_diagnosis_valid(package_copy):
    before = keys.source_hash_at("dampersim.views.discrepancy", package_copy)
    path = package_copy / "views" / "studies.py"
    path.write_text(path.read_text() + "\n# changed\n")
    assert keys.source_hash_at("dampersim.views.discrepancy", package_copy) == before
    path = package_copy / "discrepancy" / "diagnose.py"
    path.write_text(path.read_text() + "\n# changed\n")
    assert keys.source_hash_at("dampersim.views.discrepancy", package_copy) != before


def test_study_runs_are_keyed_by_the_study_code(package_copy):
    from dampersim.studies import studies

    before = keys.source_hash_at(studies.__name__, package_copy)
    path = package_copy / "studies" / "studies.py"
    path.write_text(path.read_text() + "\n# changed\n")
    assert keys.source_hash_at(studies.__name__, package_copy) != before
