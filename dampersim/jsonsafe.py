"""Strict-JSON values from analysis results: numpy types to Python, NaN/inf to None."""

from __future__ import annotations

import math

import numpy as np


def jsonable(obj):
    """``obj`` with numpy scalars and arrays turned into Python values and every
    non-finite float into None, recursively through dicts (keys as str), lists and
    tuples; anything else is returned as is."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    return obj


__all__ = ["jsonable"]
