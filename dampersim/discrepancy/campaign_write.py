"""Writing a campaign folder (the format of :mod:`dampersim.discrepancy.campaign`): one
time series per test point and the manifest, every file written atomically."""

from __future__ import annotations

import json
import os

import numpy as np

from dampersim.discrepancy.campaign import MANIFEST, MANIFEST_COLUMNS
from dampersim.errors import InputError
from dampersim.fileio import write_parquet_atomic, write_text_atomic


def write_point(path, point, fmt: str = "parquet", columns: dict | None = None) -> dict:
    """Write one MeasuredPoint's series into campaign folder ``path`` (``points/ID.fmt``,
    float32 series and float64 time, atomic) and return its manifest row, with the extra
    manifest ``columns`` (readers ignore columns they do not know)."""
    import pandas as pd

    if fmt not in ("parquet", "csv"):
        raise InputError(f"format {fmt!r}: accepted is parquet or csv")
    os.makedirs(os.path.join(path, "points"), exist_ok=True)
    rel = f"points/{point.id}.{fmt}"
    cols = {
        "time_s": point.time,
        "input_torque_nm": point.input_torque,
        "output_torque_nm": point.output_torque,
        "input_speed_rpm": point.input_speed_rpm,
        "output_speed_rpm": point.output_speed_rpm,
    }
    if point.windup is not None:
        cols["windup_deg"] = np.degrees(point.windup)
    df = pd.DataFrame({k: np.asarray(v, dtype=np.float64 if k == "time_s" else np.float32) for k, v in cols.items()})
    if fmt == "parquet":
        write_parquet_atomic(df, os.path.join(path, rel))
    else:
        write_text_atomic(os.path.join(path, rel), df.to_csv(index=False, float_format="%.6g"))
    return {"id": point.id, "kind": point.kind, "speed_rpm": point.speed_rpm, "mean_torque_nm": point.mean_torque_nm,
            "file": rel, "sample_rate_hz": point.sample_rate_hz, **(columns or {})}


def write_manifest(path, rows, name: str = "", description: str = "", metadata: dict | None = None) -> None:
    """Write the manifest of ``rows`` (from :func:`write_point`, in order) and campaign.json
    (name, description and the further entries of ``metadata``) into folder ``path``."""
    import pandas as pd

    columns = list(MANIFEST_COLUMNS) + [c for c in dict.fromkeys(k for r in rows for k in r) if c not in MANIFEST_COLUMNS]
    write_text_atomic(os.path.join(path, MANIFEST), pd.DataFrame(list(rows), columns=columns).to_csv(index=False))
    meta = {"name": name or os.path.basename(os.path.abspath(path)), "description": description, **(metadata or {})}
    write_text_atomic(os.path.join(path, "campaign.json"), json.dumps(meta, indent=2))


def write_campaign(path, points, name: str = "", description: str = "", fmt: str = "parquet",
                   metadata: dict | None = None, point_columns: dict | None = None) -> None:
    """Write ``points`` (list of MeasuredPoint) as a campaign folder; every file atomic.

    Series are stored as float32 (``fmt`` 'parquet' or 'csv'). Existing files of the same
    names are replaced atomically; other files are left alone. ``metadata``: further
    entries of campaign.json (e.g. where the data came from); ``point_columns``: {point id:
    {column: value}}, extra manifest columns (readers ignore columns they do not know).
    """
    rows = [write_point(path, p, fmt, (point_columns or {}).get(p.id)) for p in points]
    write_manifest(path, rows, name, description, metadata)


__all__ = ["write_point", "write_manifest", "write_campaign"]
