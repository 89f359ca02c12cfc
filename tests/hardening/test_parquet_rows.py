"""A Parquet file's row count comes from its row groups: a footer whose file-level
``num_rows`` under-reports what the row groups hold (a crafted file) is refused, naming the
file, before any data is read.

Budget: 5 s per case: writing and reading the metadata of a 1000-row file takes
milliseconds; nothing is loaded.
"""

from __future__ import annotations

import time

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from dampersim.discrepancy import campaign as C
from dampersim.errors import InputError

CASE_BUDGET_S = 5.0


@pytest.fixture(autouse=True)
def budget():
    t0 = time.perf_counter()
    yield
    assert time.perf_counter() - t0 < CASE_BUDGET_S


def parquet(tmp_path, rows=1000, group=250):
    path = tmp_path / "p1.parquet"
    table = pa.table({"time": np.arange(rows) * 1e-3, "torque_in": np.zeros(rows)})
    pq.write_table(table, path, row_group_size=group)
    return str(path)


class Footer:
    """The real metadata of a file with its file-level row count replaced (what a crafted
    footer says), row groups unchanged."""

    def __init__(self, meta, num_rows):
        self._meta, self.num_rows = meta, num_rows

    def __getattr__(self, name):
        return getattr(self._meta, name)


def test_honest_file_rows_from_its_row_groups(tmp_path):
    shape = C.file_shape(parquet(tmp_path), "camp/p1.parquet")
    assert shape["rows"] == 1000 and shape["columns"] == ["time", "torque_in"] and not shape["more"]


def test_under_reported_row_count_is_refused(tmp_path, monkeypatch):
    path = parquet(tmp_path)
    real = pq.ParquetFile

    class Crafted:
        def __init__(self, *a, **k):
            self.metadata = Footer(real(*a, **k).metadata, 10)

    monkeypatch.setattr(pq, "ParquetFile", Crafted)
    with pytest.raises(InputError) as exc:
        C.file_shape(path, "camp/p1.parquet")
    text = str(exc.value)
    assert "camp/p1.parquet" in text and "gives 10 rows" in text and "row groups hold 1000" in text
    assert "accepted is a file whose row count matches its row groups" in text
