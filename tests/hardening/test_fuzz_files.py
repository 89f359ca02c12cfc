"""Property-based fuzzing of the file readers a browser can feed: the TOML parameter loader
and the campaign manifest reader. Whatever arrives, the only exceptions are the documented
ones (ParameterError / InputError, each naming what was wrong), and every example stays
within a time and memory budget.

Budgets: hypothesis's per-example deadline of 2 s (a valid parameter set loads in ~5 ms,
a manifest of a few rows is read in ~20 ms; 2 s leaves room for 2 loaded cores and the
first call's imports); Python allocations per example below 32 MB (the readers are bounded
to 1 MB of TOML and 4 MB of manifest; a reader that expanded its input would exceed it).
The whole module runs in about 15 s.
"""

from __future__ import annotations

import tracemalloc

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from dampersim.discrepancy import campaign as C
from dampersim.discrepancy.campaign_write import write_campaign
from dampersim.discrepancy.upload import UPLOAD_LIMITS
from dampersim.errors import InputError, ParameterError
from dampersim.parameters import default_parameters, io as pio

from tests.hardening.test_uploads import point

DOCUMENTED = (ParameterError, InputError)
MEMORY_BUDGET = 32 * 2**20  # see the module docstring
FUZZ = settings(max_examples=120, deadline=2000, suppress_health_check=[HealthCheck.too_slow,
                                                                        HealthCheck.function_scoped_fixture])


def within_memory(fn):
    """Run ``fn`` and return its result or documented error; any other exception fails the
    test (re-raised), as does an allocation peak above :data:`MEMORY_BUDGET`."""
    tracemalloc.start()
    try:
        try:
            return fn()
        except DOCUMENTED as exc:
            assert "Traceback" not in str(exc)
            return exc
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert peak < MEMORY_BUDGET, f"allocated {peak / 2**20:.0f} MB"


# ----------------------------------------------------------------------------- TOML loader
scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(10**400), max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=30),
    st.sampled_from(["1e400", "-0", "nan", "inf", "pi", "held", "pi ", "transducer", "", "0x10", "1_000"]),
)
values = st.recursive(scalars, lambda kids: st.one_of(st.lists(kids, max_size=4),
                                                      st.dictionaries(st.text(max_size=12), kids, max_size=4)),
                      max_leaves=12)


def _paths(d, pre=()):
    for k, v in d.items():
        yield pre + (k,)
        if isinstance(v, dict):
            yield from _paths(v, pre + (k,))
        elif isinstance(v, list):
            for i, e in enumerate(v):
                if isinstance(e, dict):
                    yield from _paths(e, pre + (k, i))


BASE = pio.to_dict(default_parameters())
BASE_PATHS = list(_paths(BASE))


def _set(d, path, value):
    for k in path[:-1]:
        d = d[k]
    if value is _DELETE:
        del d[path[-1]]
    else:
        d[path[-1]] = value


_DELETE = object()


@FUZZ
@given(text=st.one_of(st.text(max_size=400), st.binary(max_size=400).map(lambda b: b.decode("latin-1"))))
def test_toml_text_gives_only_parameter_errors(text):
    within_memory(lambda: pio.loads_toml(text))


@FUZZ
@given(edits=st.lists(st.tuples(st.sampled_from(BASE_PATHS), st.one_of(values, st.just(_DELETE))), min_size=1, max_size=4),
       extra=st.dictionaries(st.text(max_size=12), values, max_size=2))
def test_edited_parameter_sets_give_only_parameter_errors(edits, extra):
    import copy

    data = copy.deepcopy(BASE)
    for path, value in edits:
        try:
            _set(data, path, value)
        except (KeyError, TypeError, IndexError):
            continue  # an earlier edit replaced the table this path runs through
    data.update(extra)
    out = within_memory(lambda: pio.system_from_dict(data))
    if not isinstance(out, Exception):
        assert out.rig.elements  # a set that loads is a complete, validated one


@FUZZ
@given(n=st.integers(min_value=0, max_value=3000), body=st.sampled_from(["{}", '{ name = "e" }', "1", '"x"']))
def test_rig_element_lists_of_any_length_give_only_parameter_errors(n, body):
    data = pio.to_dict(default_parameters())
    text = pio.dumps_toml(default_parameters()).replace("[[rig.elements]]", "[[rig.old]]", 1)
    out = within_memory(lambda: pio.loads_toml(text + f"\n[rig]\nextra = [{', '.join([body] * n)}]\n"))
    assert isinstance(out, ParameterError)
    data["rig"]["elements"] = [{"name": f"e{i}", "inertia": 0.1} for i in range(n)]
    out = within_memory(lambda: pio.system_from_dict(data))
    if n > 64:
        assert isinstance(out, ParameterError) and f"{n} elements" in str(out) and "at most 64" in str(out)


# ----------------------------------------------------------------------------- manifest reader
@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A campaign folder with two valid point files (Parquet and CSV); each example writes
    its own manifest.csv into it."""
    root = tmp_path_factory.mktemp("fuzz-campaign") / "c"
    write_campaign(root, [point("p0")], name="c")
    write_campaign(root, [point("p1", rpm=1300.0)], name="c", fmt="csv")
    (root / "manifest.csv").unlink()
    return root


FILES = ["points/p0.parquet", "points/p1.csv", "./points/p0.parquet", "points//p0.parquet", "points/none.parquet",
         "points", "", " ", "../c/points/p0.parquet", "points/p0.PARQUET", "manifest.csv", "campaign.json", "p0.txt"]
cells = st.one_of(st.text(max_size=12).filter(lambda t: "\n" not in t and "\r" not in t and '"' not in t),
                  st.sampled_from(["torsional", "ramp", "nan", "inf", "-inf", "1e400", "1500", "200", "5000", "0", "-1",
                                   "", "TORSIONAL ", "5e3"]))
rows = st.fixed_dictionaries({
    "id": cells, "kind": cells, "speed_rpm": cells, "mean_torque_nm": cells,
    "file": st.one_of(st.sampled_from(FILES), cells), "sample_rate_hz": cells,
})


def _read_all(folder):
    camp = C.read_campaign(folder)
    assert camp.rows >= 0 and all(isinstance(q.message, str) for q in camp.problems)
    C.scan_campaign(folder, UPLOAD_LIMITS)
    C.read_campaign(folder, limits=UPLOAD_LIMITS)
    C.paths_outside(folder)
    return camp


@FUZZ
@given(text=st.one_of(st.text(max_size=600), st.binary(max_size=600).map(lambda b: b.decode("latin-1"))))
def test_manifest_text_gives_only_input_errors(folder, text):
    (folder / "manifest.csv").write_bytes(text.encode("utf-8", "surrogatepass"))
    within_memory(lambda: _read_all(folder))


@FUZZ
@given(table=st.lists(rows, max_size=12), columns=st.permutations(list(C.MANIFEST_COLUMNS)),
       drop=st.sets(st.sampled_from(C.MANIFEST_COLUMNS), max_size=1), extra=st.booleans())
def test_manifest_rows_give_only_input_errors(folder, table, columns, drop, extra):
    cols = [c for c in columns if c not in drop] + (["note"] if extra else [])
    lines = [",".join(cols)] + [",".join(r.get(c, "x") for c in cols) for r in table]
    (folder / "manifest.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    out = within_memory(lambda: _read_all(folder))
    if isinstance(out, C.Campaign):
        ids = [p.id for p in out.points]
        assert len(ids) == len(set(ids))  # a point is never read twice
        files = [p.file for p in out.points]
        assert len(files) == len({f.replace("./", "").replace("//", "/") for f in files})


def test_fuzz_folder_is_left_as_it_was(folder):
    """The reader never writes: only the files the fixture wrote (and the manifest the
    examples wrote) are there."""
    names = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    assert set(names) <= {"campaign.json", "manifest.csv", "points/p0.parquet", "points/p1.csv"}, names
