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


def private_dir(*parts: str) -> Path:
    """``cache_dir()/<parts>``, created with mode 0700 (and its missing parents), checked
    before use.

    Views, job records and uploads under it are read back by the server, so nobody else
    may write there: the folder (and the cache directory itself) is refused with an
    :class:`~dampersim.errors.InputError` when it is owned by another user or is group- or
    world-writable. The message says which folder and what is accepted.
    """
    from dampersim.errors import InputError

    root = cache_dir()
    path = root.joinpath(*parts)
    try:
        os.makedirs(root, mode=0o700, exist_ok=True)
        os.makedirs(path, mode=0o700, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cache folder {path.name!r} cannot be created ({exc.strerror or exc}); "
                         f"set {CACHE_DIR_ENV} to a writable folder") from None
    for folder in (root, path) if path != root else (root,):
        _check_private(folder, InputError)
    return path


def _check_private(folder: Path, error) -> None:
    """Refuse ``folder`` unless this user owns it and only this user may write to it."""
    if os.name != "posix":
        return
    st = os.stat(folder)
    if st.st_uid != os.getuid():
        raise error(f"cache folder {folder.name!r} belongs to another user (uid {st.st_uid}): accepted is a folder "
                    f"owned by the user running dampersim; set {CACHE_DIR_ENV} to one")
    if st.st_mode & 0o022:
        raise error(f"cache folder {folder.name!r} may be written by other users (mode {oct(st.st_mode & 0o777)}): "
                    f"accepted is a folder only its owner may write (chmod go-w)")


__all__ = ["CACHE_DIR_ENV", "repo_root", "cache_dir", "private_dir"]
