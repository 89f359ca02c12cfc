"""Atomic file output: every file dampersim writes appears whole or not at all."""

from __future__ import annotations

import os
import tempfile

from dampersim.errors import InputError


def _umask() -> int:
    """The process umask, read without changing it (os.umask would, for all threads)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return 0o022


def atomic_write(path, write, suffix=".tmp") -> str:
    """Call ``write(tmp_path)`` on a temporary file next to ``path``, give it the usual
    permissions (mkstemp makes it private) and rename it over ``path``. Returns the
    absolute path. A missing folder is an InputError naming it."""
    path = os.path.abspath(os.fspath(path))
    directory = os.path.dirname(path)
    if not os.path.isdir(directory):
        raise InputError(f"output {path!r}: folder {directory!r} does not exist")
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".dampersim-", suffix=suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_text_atomic(path, text: str) -> str:
    """Write ``text`` (UTF-8) to ``path`` atomically."""

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    return atomic_write(path, write)


def write_parquet_atomic(frame, path) -> str:
    """Write a pandas DataFrame as Parquet to ``path`` atomically (no index)."""
    return atomic_write(path, lambda tmp: frame.to_parquet(tmp, index=False), suffix=".parquet.tmp")
