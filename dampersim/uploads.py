"""Browser uploads: the bytes of a ``data:...;base64,...`` upload, refused when malformed or too large."""

from __future__ import annotations

import base64
import binascii

from dampersim.errors import InputError


def decode_upload(contents, name: str, accepted: str, max_bytes: int, size_text, *, size_accepted: str | None = None,
                  base64_accepted: bool = True) -> bytes:
    """The bytes of a browser upload (``data:...;base64,...``).

    Raises InputError naming the file (``name``) for an upload without content, data
    that is not base64 and more than ``max_bytes`` bytes (``size_text(n)`` writes the size,
    ``size_accepted`` replaces ``accepted`` in that message); ``base64_accepted=False``
    leaves "accepted is ..." out of the base64 message.
    """
    if not isinstance(contents, str) or "," not in contents:
        raise InputError(f"{name}: the upload arrived without content; accepted is {accepted}")
    encoded = contents.split(",", 1)[1]
    # base64 carries 3 bytes in 4 characters: a text longer than that of max_bytes is
    # refused before it is decoded (the size given is the file's, from the text's length)
    if len(encoded) > 4 * (max_bytes // 3 + 1) + 4:
        raise InputError(f"{name} is {size_text(len(encoded.rstrip('=')) * 3 // 4)}; accepted is {size_accepted or accepted}")
    try:
        data = base64.b64decode(encoded, validate=True)
    except (binascii.Error, ValueError):
        raise InputError(f"{name}: the upload is not valid base64 data"
                         + (f"; accepted is {accepted}" if base64_accepted else "")) from None
    if len(data) > max_bytes:
        raise InputError(f"{name} is {size_text(len(data))}; accepted is {size_accepted or accepted}")
    return data


__all__ = ["decode_upload"]
