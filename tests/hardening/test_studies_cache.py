"""The study cache (single runs of the chapter 7 studies): a private folder, JSON rows
that round-trip, and a planted pickle row refused (computed again, never unpickled).

Budget: each case opens a SQLite store a few times and runs a stand-in function instead
of the simulation; 5 s covers a loaded 2-core machine.
"""

from __future__ import annotations

import os
import pickle
import sqlite3
import stat
import time
from pathlib import Path

import numpy as np
import pytest

from dampersim import default_parameters
from dampersim.errors import InputError
from dampersim.studies import _common as C

CASE_BUDGET_S = 5.0
PICKLE_HEADERS = (b"\x80\x02", b"\x80\x03", b"\x80\x04", b"\x80\x05")
CALLS = []


@pytest.fixture(autouse=True)
def budget(cache_dir):
    CALLS.clear()
    t0 = time.perf_counter()
    yield
    assert time.perf_counter() - t0 < CASE_BUDGET_S


def stand_in(system, excitation, duration):
    """What a study's run function returns: JSON-able results (here without simulating)."""
    CALLS.append(duration)
    return {"duration": duration, "mr": [1.5, float("nan"), 2.25], "pair": (2, "outer"), "n": 3,
            "nested": {"ok": True, "none": None}, "arr": np.linspace(0.0, 1.0, 5)}


def jobs():
    system = default_parameters()
    return [(system, C.point(1500, 200, ((2.0, 300.0, 0.0),)).excitation(), d) for d in (1.2, 1.3)]


def run(js):
    return C.cached_runs("probe", stand_in, js, C.Progress(None, len(js)), parallel=False)


def test_rows_round_trip_in_a_private_folder(cache_dir):
    js = jobs()
    first = run(js)
    assert CALLS == [1.2, 1.3]
    again = run(js)
    assert CALLS == [1.2, 1.3]  # the second time every run comes from the cache
    for a, b in zip(first, again):
        assert b["duration"] == a["duration"] and b["pair"] == (2, "outer") and b["n"] == 3
        assert b["mr"][0] == 1.5 and np.isnan(b["mr"][1]) and b["mr"][2] == 2.25
        assert b["nested"] == {"ok": True, "none": None} and np.array_equal(b["arr"], a["arr"])
    folder = cache_dir / C.STUDIES_SUBDIR
    assert stat.S_IMODE(os.stat(folder).st_mode) == 0o700
    con = sqlite3.connect(folder / "cache.db")
    rows = con.execute("SELECT raw, mode, value FROM Cache").fetchall()
    con.close()
    assert len(rows) == 2 and all(r[0] == 1 and r[1] != 4 for r in rows)  # text keys, no diskcache MODE_PICKLE
    for r in rows:
        blob = bytes(r[2])
        assert blob.startswith(b"DSV1J\n") and not any(h in blob for h in PICKLE_HEADERS)


def test_a_planted_pickle_row_is_refused(cache_dir, tmp_path):
    js = jobs()
    run(js)
    marker = tmp_path / "code-ran"

    class Payload:
        def __reduce__(self):
            return (Path.touch, (marker,))

    con = sqlite3.connect(cache_dir / C.STUDIES_SUBDIR / "cache.db")
    con.execute("UPDATE Cache SET mode = 4, value = ?", (pickle.dumps(Payload()),))
    con.commit()
    con.close()
    CALLS.clear()
    out = run(js)
    assert not marker.exists()
    assert CALLS == [1.2, 1.3] and out[0]["duration"] == 1.2  # refused rows are computed again
    CALLS.clear()
    run(js)
    assert CALLS == []  # and stored as JSON this time


def test_a_folder_others_may_write_is_refused(cache_dir):
    folder = cache_dir / C.STUDIES_SUBDIR
    folder.mkdir(parents=True, mode=0o700)
    os.chmod(folder, 0o777)
    with pytest.raises(InputError) as exc:
        run(jobs())
    assert "'studies'" in str(exc.value) and "0o777" in str(exc.value) and "chmod go-w" in str(exc.value)
    assert CALLS == [] and not (folder / "cache.db").exists()
