"""Cache folders and view entries: folders 0700 and refused when others may write them, view
and parameter-set entries stored as JSON (never pickle, a planted pickle is not loaded),
and a damaged cache database recovered.

Budget: each case opens a SQLite store or two; 5 s covers a loaded 2-core machine.
"""

from __future__ import annotations

import logging
import os
import pickle
import sqlite3
import stat
import time
from pathlib import Path

import numpy as np
import plotly.graph_objects as go
import pytest

from dampersim.errors import InputError
from dampersim.views import store

CASE_BUDGET_S = 5.0
#: pickle protocol 2-5 headers (0x80 then the protocol number)
PICKLE_HEADERS = (b"\x80\x02", b"\x80\x03", b"\x80\x04", b"\x80\x05")


@pytest.fixture(autouse=True)
def budget(cache_dir):
    t0 = time.perf_counter()
    yield
    store.close_stores()
    assert time.perf_counter() - t0 < CASE_BUDGET_S


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def sample_view():
    fig = go.Figure(go.Scatter(x=np.arange(4.0), y=np.array([1.0, np.nan, 3.0, 2.0])))
    return {"kind": "probe", "figures": {"f": fig.to_dict()}, "rows": [{"order": 2.0, "mr": None}],
            "pair": (1, "a"), "spectrum": np.linspace(0, 1, 7, dtype=np.float32), "grid": np.eye(3),
            "flags": np.array([True, False]), "nan": float("nan"), "n": np.int64(7)}


def test_new_folders_are_private(cache_dir):
    import app
    from dampersim.sweeps.cache import ResultCache

    store.view_store()
    store.store_parameter_set(__import__("dampersim").default_parameters())
    with ResultCache() as rc:
        len(rc)
    app.job_manager()
    for sub in ("views", "parameter-sets", "results", "callbacks"):
        assert mode(cache_dir / sub) == 0o700, sub
    assert mode(cache_dir) & 0o077 == 0


@pytest.mark.parametrize("target", ["root", "views"])
def test_world_writable_folder_refused(cache_dir, target):
    (cache_dir / "views").mkdir(parents=True, mode=0o700)
    os.chmod(cache_dir if target == "root" else cache_dir / "views", 0o777)
    with pytest.raises(InputError) as exc:
        store.view_store()
    message = str(exc.value)
    assert "may be written by other users" in message and "0o777" in message and "chmod go-w" in message
    # the page is not broken: the view is simply not cached, and nothing was written there
    store.save_entry("k", {"a": 1})
    assert store.load_entry("k") is None
    assert not (cache_dir / "views" / "cache.db").exists()


def test_view_entries_are_json_not_pickle(cache_dir):
    view = sample_view()
    store.save_entry("probe", view)
    store.save_entry("big", {**view, "grid": np.random.default_rng(1).random((100, 100))})  # a value file
    store.close_stores()
    folder = cache_dir / "views"
    con = sqlite3.connect(folder / "cache.db")
    rows = con.execute("SELECT key, raw, mode, value, filename FROM Cache").fetchall()
    con.close()
    assert {r[0] for r in rows} == {"probe", "big"} and all(r[1] == 1 for r in rows)  # text keys
    assert all(r[2] != 4 for r in rows)  # diskcache MODE_PICKLE
    blobs = [bytes(r[3]) if r[3] is not None else (folder / r[4]).read_bytes() for r in rows]
    assert any(r[4] for r in rows)  # the large entry went to a file: checked too
    for blob in blobs:
        assert blob.startswith(b"DSV1J\n") and not any(h in blob for h in PICKLE_HEADERS)
    raw = (folder / "cache.db").read_bytes()
    assert not any(h + b"\x95" in raw for h in PICKLE_HEADERS[2:])  # protocol 4/5 frame opcode


def test_view_entries_round_trip(cache_dir):
    view = sample_view()
    store.save_entry("probe", view)
    store.close_stores()
    got = store.load_entry("probe")
    assert got["kind"] == "probe" and got["pair"] == (1, "a") and got["rows"] == view["rows"]
    assert got["spectrum"].dtype == np.float32 and np.array_equal(got["spectrum"], view["spectrum"])
    assert got["grid"].shape == (3, 3) and np.array_equal(got["grid"], np.eye(3))
    assert got["flags"].dtype == bool and np.isnan(got["nan"]) and got["n"] == 7
    assert got["figures"]["f"]["data"][0]["type"] == "scatter"
    assert go.Figure(got["figures"]["f"]).data[0].type == "scatter"
    text = store.store_parameter_set(__import__("dampersim").default_parameters())
    store.close_stores()
    assert "inertias" in store.load_parameter_set(text)


def test_a_planted_pickle_is_not_loaded(cache_dir, tmp_path):
    store.save_entry("probe", {"a": 1})
    store.close_stores()
    marker = tmp_path / "code-ran"

    class Payload:
        def __reduce__(self):
            return (Path.touch, (marker,))

    con = sqlite3.connect(cache_dir / "views" / "cache.db")
    con.execute("UPDATE Cache SET mode = 4, value = ? WHERE key = 'probe'", (pickle.dumps(Payload()),))
    con.commit()
    con.close()
    assert store.load_entry("probe") is None
    assert store.load_view("probe") is None
    assert not marker.exists()


def test_a_value_that_is_not_json_is_not_stored(cache_dir):
    store.save_entry("odd", {"x": object()})
    assert store.load_entry("odd") is None


@pytest.mark.parametrize("close_first", [True, False])
def test_corrupted_database_recovered(cache_dir, caplog, close_first):
    store.save_entry("probe", {"a": 1})
    set_id = store.store_parameter_set(__import__("dampersim").default_parameters())
    if close_first:
        store.close_stores()
    db = cache_dir / "views" / "cache.db"
    db.write_bytes(os.urandom(4096) + b"garbage" * 1000)
    for extra in ("cache.db-wal", "cache.db-shm"):
        (cache_dir / "views" / extra).unlink(missing_ok=True)
    with caplog.at_level(logging.WARNING, logger="dampersim.views.store"):
        if not close_first:  # damaged under an open connection: nothing may raise meanwhile
            store.save_entry("other", {"b": 1})
            store.load_entry("other")
            store.close_stores()  # the next process (or a restart) opens the damaged file
        assert store.load_entry("probe") is None  # no exception reaches the page
    assert any("damaged database" in r.getMessage() for r in caplog.records)
    aside = [p.name for p in cache_dir.iterdir() if p.name.startswith("views.corrupt-")]
    assert len(aside) == 1
    store.save_entry("probe", {"a": 2})  # the fresh store works
    assert store.load_entry("probe") == {"a": 2}
    assert store.load_parameter_set(set_id) is not None  # the other store was untouched
    assert mode(cache_dir / "views") == 0o700
