"""Where the editor may write, and how it tells one file, or one version of a file, from another."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["PACKAGE", "same_file", "signature", "writable_folder"]

#: The package's folder, never written to (the bundled sample lives in it).
PACKAGE = Path(__file__).resolve().parents[1]


def writable_folder(image_path: Path) -> bool:
    """Whether the editor writes next to ``image_path``: a folder it may write to, and not the package's (the bundled sample)."""
    folder = image_path.resolve().parent
    return not folder.is_relative_to(PACKAGE) and os.access(folder, os.W_OK | os.X_OK)


def same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name one file (links resolved); False when either cannot be looked at."""
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def signature(path: Path) -> tuple[int, ...] | None:
    """The file's device, inode, size and time of change (None when there is none): what tells one version from the next."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
