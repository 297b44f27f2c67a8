"""Files written whole or not at all: shared by the handles document and the image writers."""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

__all__ = ["atomic_write_bytes", "remove_leftovers"]

#: The temporary files are ``.NAME.`` and eight random characters (:func:`tempfile.mkstemp`'s) and ``.tmp``, beside ``NAME``.
_SUFFIX = ".tmp"

# The process's umask, read once at import (reading it means setting it, which is not thread-safe later).
_UMASK = os.umask(0o022)
os.umask(_UMASK)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    Either ``path`` holds all of ``data`` afterwards, or it is as it was (and no temporary
    file is left); an :class:`OSError` says why. The file gets the permissions a plain
    ``open(path, "wb")`` would give it: an existing file's, else ``0o666`` less the umask
    (a temporary file alone would be readable by its owner only).
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode & 0o7777
    except FileNotFoundError:
        mode = 0o666 & ~_UMASK
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=_SUFFIX, dir=path.parent or ".")
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def remove_leftovers(path: Path, suffix: str = _SUFFIX) -> None:
    """Remove the temporary files an :func:`atomic_write_bytes` of ``path`` killed mid-write left, never another file.

    For a write that may be retried after its process died (a Dask worker killed, say):
    ``atomic_write_bytes`` cleans up after itself whenever it can, but not after a kill.
    ``suffix`` names the other writers' temporary files made the same way
    (``.NAME.``, eight random characters and the suffix; a video's suffix is ``.part``).
    """
    path = Path(path)
    pattern = re.compile(re.escape(f".{path.name}.") + r"[a-z0-9_]{8}" + re.escape(suffix))
    try:
        names = os.listdir(path.parent)
    except OSError:
        return
    for name in names:
        if pattern.fullmatch(name):
            (path.parent / name).unlink(missing_ok=True)
