"""Where dampersim keeps its files: the repository root and the cache directory."""

from __future__ import annotations

import os
from pathlib import Path

#: Environment variable naming the cache directory (read at call time).
CACHE_DIR_ENV = "DAMPERSIM_CACHE_DIR"


def repo_root() -> Path:
    """Directory that contains the ``dampersim`` package (the repository in a checkout)."""
    return Path(__file__).resolve().parent.parent


def cache_dir() -> Path:
    """Absolute cache directory: ``$DAMPERSIM_CACHE_DIR`` if set (read now), else
    ``cache/`` at the repository root. Sweep points, views, study runs and uploads live in
    folders below it."""
    env = os.environ.get(CACHE_DIR_ENV, "").strip()
    base = Path(env).expanduser() if env else repo_root() / "cache"
    return Path(os.path.abspath(base))


__all__ = ["CACHE_DIR_ENV", "repo_root", "cache_dir"]
