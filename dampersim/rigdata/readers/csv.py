"""Reader of wide delimited-text exports (CSV): a header row, a time column, channel columns.

Accepted layout:

- Delimiter: tab, ``;`` or ``,`` (the one the header row uses most); decimal comma is
  recognised when the delimiter is not ``,``. Encoding UTF-8 (with or without BOM), else
  Windows-1252. Blank lines are skipped.
- Row 1: column names. Units either in the names, ``name [unit]`` or ``name (unit)``,
  or in row 2, a row of unit texts (recognised because none of its cells is a number).
  The channel name is the header text without the unit part.
- Time columns: named ``t``, ``time``, ``Time``, ``time_s`` or ``time`` plus a suffix
  (``time_2``, ``Time fast``), in s (no unit, ``s``, a ``_s`` suffix), ``ms`` or ``us``.
  The first column must be a time column. Each time column is the time base of the columns
  after it up to the next time column (group id: the time column's name), so exports with
  several sample rates are read as several groups.
- Every cell of a group is a number, except that a group shorter than the file ends with
  empty cells (all its columns empty from the same row on). Time stamps increase
  strictly. A column with an empty header and no values (a trailing delimiter) is ignored.

Anything else is an InputError naming the file, the row and the column. A file cut
inside a number of its last column cannot be told from a complete one (the cut number
is a shorter number); a cut anywhere else leaves empty cells and is reported. Memory:
the whole table is read into memory when the file is opened (pandas).
"""

from __future__ import annotations

import csv as _csv
import io
import re

import numpy as np

from dampersim.errors import InputError
from dampersim.rigdata.readers import Recording, SampledTime, _one_line, is_time_name

ACCEPTED_LAYOUT = ("accepted is a header row (units as 'name [unit]', 'name (unit)' or a second row of units), "
                   "a time column first (t, time, time_s in s, ms or us) and numeric cells")
_UNIT_IN_NAME = re.compile(r"^(.*?)\s*(?:\[([^\]]*)\]|\(([^)]*)\))\s*$")
_TIME_SCALE = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
_NUMBER = re.compile(r"^\s*[-+]?(\d+([.,]\d*)?|[.,]\d+)([eE][-+]?\d+)?\s*$|^\s*[-+]?(nan|inf)\s*$", re.IGNORECASE)


def _split_name(text: str) -> tuple[str, str]:
    text = text.strip()
    m = _UNIT_IN_NAME.match(text)
    if m and m.group(1):
        return m.group(1).strip(), (m.group(2) if m.group(2) is not None else m.group(3)).strip()
    return text, ""


def _time_scale(name: str, unit: str, where: str) -> float:
    if not unit:
        lower = name.lower()
        unit = "ms" if lower.endswith("_ms") else "us" if lower.endswith("_us") else ""
    scale = _TIME_SCALE.get(unit.strip().lower())
    if scale is None:
        raise InputError(f"{where}: time unit {unit!r}; accepted are s, ms and us")
    return scale


def _decode(path: str) -> tuple[str, str]:
    with open(path, "rb") as fh:
        raw = fh.read()
    for enc in ("utf-8-sig", "cp1252"):
        try:
            return raw.decode(enc), enc
        except UnicodeDecodeError:
            continue
    raise InputError(f"{path}: text encoding not recognised; accepted are UTF-8 and Windows-1252")


class CsvRecording(Recording):
    """A wide CSV export read whole into memory (module doc: accepted layout)."""

    format = "csv"
    accepted = ACCEPTED_LAYOUT

    def __init__(self, path):
        super().__init__(path)
        text, _enc = _decode(self.path)
        lines = [(i + 1, line) for i, line in enumerate(text.splitlines()) if line.strip()]
        if len(lines) < 2:
            raise InputError(f"{self.path}: fewer than two non-blank lines; {ACCEPTED_LAYOUT}")
        header_line = lines[0][1]
        delim = max(("\t", ";", ","), key=header_line.count)
        header = next(_csv.reader([header_line], delimiter=delim))
        second = next(_csv.reader([lines[1][1]], delimiter=delim))
        unit_row = not any(_NUMBER.match(c) for c in second if c.strip())
        data_lines = lines[2:] if unit_row else lines[1:]
        if not data_lines:
            raise InputError(f"{self.path}: no data rows; {ACCEPTED_LAYOUT}")
        decimal = "."
        if delim != "," and re.search(r"\d,\d", data_lines[0][1]) and not re.search(r"\d\.\d", data_lines[0][1]):
            decimal = ","
        names, units = [], []
        for k, cell in enumerate(header):
            name, unit = _split_name(cell)
            row_unit = second[k].strip() if unit_row and k < len(second) else ""
            if unit and row_unit and unit != row_unit:
                raise InputError(f"{self.path}: column {k + 1} {name!r} has unit {unit!r} in its name and "
                                 f"{row_unit!r} in the unit row; {ACCEPTED_LAYOUT}")
            names.append(name)
            units.append(unit or row_unit)
        table = self._table(data_lines, delim, decimal, len(header))
        self._columns(names, units, table, [ln for ln, _ in data_lines])

    def _table(self, data_lines, delim, decimal, width) -> np.ndarray:
        import pandas as pd

        body = "\n".join(line for _, line in data_lines)
        try:
            frame = pd.read_csv(io.StringIO(body), sep=delim, header=None, decimal=decimal, index_col=False,
                                skip_blank_lines=True, engine="c", low_memory=False)
        except Exception as exc:  # noqa: BLE001 - any parse failure is bad input
            raise InputError(f"{self.path}: not a readable table ({_one_line(exc)}); {ACCEPTED_LAYOUT}") from None
        if frame.shape[1] > width:
            raise InputError(f"{self.path}: line {data_lines[0][0]} has {frame.shape[1]} fields, the header {width}; "
                             f"{ACCEPTED_LAYOUT}")
        for k in range(frame.shape[1], width):
            frame[k] = np.nan
        for k in frame.columns:
            if frame[k].dtype.kind not in "iuf":
                values = pd.to_numeric(frame[k], errors="coerce")
                bad = np.flatnonzero(values.isna().to_numpy() & frame[k].notna().to_numpy())
                if bad.size:
                    row = data_lines[int(bad[0])][0]
                    raise InputError(f"{self.path}: line {row} column {k + 1}: {frame[k].iloc[int(bad[0])]!r} is not a "
                                     f"number; {ACCEPTED_LAYOUT}")
                frame[k] = values
        return frame.to_numpy(dtype=np.float64)

    def _columns(self, names, units, table, line_numbers):
        keep = [k for k in range(len(names)) if names[k] or not np.all(np.isnan(table[:, k]))]
        if not keep or not is_time_name(names[keep[0]]):
            raise InputError(f"{self.path}: first column {names[keep[0]] if keep else ''!r} is not a time column; "
                             f"{ACCEPTED_LAYOUT}")
        groups = []  # [time column, [data columns]]
        for k in keep:
            if not names[k]:
                raise InputError(f"{self.path}: column {k + 1} has no name; {ACCEPTED_LAYOUT}")
            if is_time_name(names[k]):
                groups.append((k, []))
            else:
                groups[-1][1].append(k)
        for tk, members in groups:
            where = f"{self.path} time column {names[tk]!r}"
            if not members:
                raise InputError(f"{where}: no channel columns follow it; {ACCEPTED_LAYOUT}")
            length = self._length(table[:, tk], where, line_numbers)
            for k in members:
                col = table[:, k]
                missing = np.flatnonzero(np.isnan(col[:length]))
                extra = np.flatnonzero(~np.isnan(col[length:]))
                if missing.size or extra.size:
                    row = line_numbers[int(missing[0])] if missing.size else line_numbers[length + int(extra[0])]
                    raise InputError(f"{self.path}: line {row} column {k + 1} {names[k]!r}: "
                                     f"{'empty cell' if missing.size else 'value after the end of its time column'}; "
                                     f"accepted are numbers in every row of its time column {names[tk]!r}")
            scale = _time_scale(names[tk], units[tk], where)
            t = table[:length, tk] * scale
            tb = SampledTime(lambda lo, hi, a=t: a[lo:hi], length, where, chunk=max(length, 2))
            for k in members:
                self._add(names[k], units[k], names[tk], tb, np.ascontiguousarray(table[:length, k]))
        self._finish()

    def _length(self, column, where, line_numbers) -> int:
        empty = np.flatnonzero(np.isnan(column))
        length = int(empty[0]) if empty.size else column.size
        if np.any(~np.isnan(column[length:])):
            row = line_numbers[length]
            raise InputError(f"{where}: empty cell at line {row} before the column's end; accepted are time stamps "
                             "in every row, with empty cells only after a shorter group's last sample")
        if length == 0:
            raise InputError(f"{where}: no time stamps; {ACCEPTED_LAYOUT}")
        return length

    def _values(self, handle, lo, hi):
        return handle[lo:hi]
