"""Files written whole or not at all, the temporary files that takes and what killed runs leave of them.

Shared by the handles document, the image writers, the videos and the command line.

- :func:`temporary_file` a new hidden file beside an output, named after it
  (``.NAME.`` eight random characters and ``.tmp``, or ``.part`` for a video), locked as in
  use for as long as its descriptor is open (:func:`fcntl.flock`; the lock goes with the
  process however it ends, ``kill -9`` included);
- :func:`commit` it renamed over the output, synced to the disk first (the file, then the folder);
- :func:`atomic_output` the two together as a context manager: the block writes the temporary
  file, which is renamed over the output when the block ends normally and removed when it
  raises (an error, a cancel, Ctrl+C);
- :func:`atomic_write_bytes` bytes written so;
- :func:`remove_leftovers` what a killed run left beside an output: files named as ours
  whose lock is free (a run still writing holds its lock, and its file is left alone);
- :func:`same_file` whether two paths name one file (the same resolved path, a symbolic
  link, a hard link), and :func:`refuse_overwrites` an output that would overwrite an input
  or another output, said in one line naming both.
"""

from __future__ import annotations

import os
import re
import secrets
import stat
from collections.abc import Iterable
from pathlib import Path
from types import TracebackType

from .errors import ImageError

try:
    import fcntl
except ImportError:  # Windows: a file in use cannot be removed there anyway
    fcntl = None  # type: ignore[assignment]

__all__ = ["AtomicOutput", "atomic_output", "atomic_write_bytes", "commit", "refuse_overwrites", "remove_leftovers", "same_file", "temporary_file"]

#: A path and what it is, as a message names it: ``("--map", Path("in.npy"))``, ``("the input", ...)``.
Named = tuple[str, str | os.PathLike[str]]

#: The end of the temporary files' names: ``.NAME.``, eight random characters, ``.tmp`` (beside ``NAME``).
_SUFFIX = ".tmp"

#: Our temporary files: ``.NAME.`` and eight characters (hex digits, or :func:`tempfile.mkstemp`'s
#: letters, digits and ``_`` in earlier versions) and ``.tmp`` or ``.part`` (a video's).
_OURS = re.compile(r"\.(?P<name>.+)\.[a-z0-9_]{8}(?:\.tmp|\.part)")

# The process's umask, read once at import (reading it means setting it, which is not thread-safe later).
_UMASK = os.umask(0o022)
os.umask(_UMASK)

#: The outputs whose leftovers this process has removed already (absolute paths): once is enough.
#: Forgotten when it grows past :data:`_CLEANED_MAX` (a long batch): the next write of each then looks again.
_cleaned: set[str] = set()
_CLEANED_MAX = 10_000


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether ``a`` and ``b`` name one file: the same path once symbolic links and ``..`` are resolved, or (both existing) a hard link.

    A path that does not exist yet is compared by its resolved name only.
    """
    return not set(_identities(a, {})).isdisjoint(_identities(b, {}))


def _identities(path: str | os.PathLike[str], folders: dict[str, str]) -> list[tuple[object, ...]]:
    """What names the file at ``path``: its resolved path and, if it exists, its device and inode (hard links share them).

    ``folders`` keeps each folder resolved once (a thousand frames share one): a path is then
    resolved by its folder and a look at its own name (:func:`os.path.realpath` in full if that
    is a link).
    """
    text = os.fspath(path)
    folder, name = os.path.split(text)
    try:
        found: os.stat_result | None = os.lstat(text)
    except (OSError, ValueError):  # missing (or not a path the system takes): its name alone
        found = None
    if name in ("", ".", "..") or (found is not None and stat.S_ISLNK(found.st_mode)):
        resolved = os.path.realpath(text)
        try:
            found = os.stat(text)
        except (OSError, ValueError):  # a link to nothing
            found = None
    else:
        if folder not in folders:
            folders[folder] = os.path.realpath(folder or os.curdir)
        resolved = os.path.join(folders[folder], name)
    keys: list[tuple[object, ...]] = [("path", resolved)]
    return keys if found is None else [*keys, ("inode", found.st_dev, found.st_ino)]


def refuse_overwrites(reads: Iterable[Named], writes: Iterable[Named]) -> None:
    """Refuse outputs that name an input or another output: by the same path, a symbolic link or a hard link.

    Parameters
    ----------
    reads : iterable of (str, path-like)
        The files a command reads (its images, video, handles file, map), each with what it
        is in a message (``"the input"``, ``"the handles file"``).
    writes : iterable of (str, path-like)
        The files it writes, in order, each with what it is (``"-o"``, ``"--map"``).

    Raises
    ------
    ImageError
        One line naming both paths, the first clash found: an output that would overwrite
        an input, or two outputs that must name different files. Each path is resolved and
        looked up once, so thousands of frames cost milliseconds.
    """
    seen: dict[tuple[object, ...], tuple[str, str | os.PathLike[str], bool]] = {}  # identity -> (what, path, an output)
    folders: dict[str, str] = {}
    for what, path in reads:
        for key in _identities(path, folders):
            seen.setdefault(key, (what, path, False))
    for what, path in writes:
        keys = _identities(path, folders)
        clash = next((seen[k] for k in keys if k in seen), None)
        if clash is not None:
            other_what, other, written = clash
            same = "" if os.fspath(other) == os.fspath(path) else " (the same file)"
            if written:
                raise ImageError(f"{other_what} {other} and {what} {path}{same} must name different files")
            raise ImageError(f"{what} {path} would overwrite {other_what} {other}{same}; choose another file")
        for key in keys:
            seen[key] = (what, path, True)


def temporary_file(path: str | os.PathLike[str], suffix: str = _SUFFIX) -> tuple[int, Path]:
    """A new empty file beside ``path``, hidden and named after it, open for writing and locked as in use.

    Parameters
    ----------
    path : path-like
        The output it stands for; the file is ``.NAME.`` eight random hex digits and ``suffix``
        in the same folder (so that a rename replaces ``path`` at once).
    suffix : str
        ``".tmp"``, or ``".part"`` for a video (the two :func:`remove_leftovers` knows).

    Returns
    -------
    (int, Path)
        An open descriptor (read and write) and the file's path. The file is locked for as
        long as the descriptor is open; close it after :func:`commit`, or after removing the
        file. Its permissions are those of a new file (``0o666`` less the umask).

    Raises
    ------
    OSError
        If no file can be made there.
    """
    path = Path(path)
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}{suffix}"
        try:
            fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        if _lock(fd):
            try:
                made, named = os.fstat(fd), os.stat(tmp, follow_symlinks=False)
                if (made.st_dev, made.st_ino) == (named.st_dev, named.st_ino):
                    return fd, tmp
            except FileNotFoundError:
                pass
        os.close(fd)  # removed as a leftover between its making and its lock: another name
    raise FileExistsError(f"{path}: cannot make a temporary file beside it")


def _lock(fd: int) -> bool:
    """Lock a new file of ours as in use; False if :func:`remove_leftovers` holds it (it is removing it)."""
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # a file system without locks: the file is written unlocked
        pass
    return True


def commit(fd: int, tmp: str | os.PathLike[str], path: str | os.PathLike[str]) -> None:
    """Rename the temporary file ``tmp`` (open as ``fd``) over ``path``, synced to the disk first, then the folder.

    After a power loss ``path`` then holds either what it held or all of ``tmp``, never an
    empty file. ``fd`` stays open (the caller closes it).
    """
    os.fsync(fd)
    os.replace(tmp, path)
    try:
        folder = os.open(Path(path).parent, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:  # a folder that cannot be opened (Windows): the rename is done, its syncing left to the system
        return
    try:
        os.fsync(folder)
    except OSError:  # a file system that does not sync folders
        pass
    finally:
        os.close(folder)


class AtomicOutput:
    """A temporary file standing for an output until it is complete: see :func:`atomic_output`.

    Attributes
    ----------
    target : Path
        The output.
    path : Path
        The temporary file beside it, to be written by the ``with`` block.
    fd : int
        Its descriptor, open for reading and writing; it holds the file's lock until the block ends.
    """

    def __init__(self, target: Path, suffix: str, leftovers: bool) -> None:
        self.target = target
        if leftovers:
            remove_leftovers(target)
        self.fd, self.path = temporary_file(target, suffix)

    def __enter__(self) -> AtomicOutput:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        try:
            if kind is None:
                commit(self.fd, self.path, self.target)
        except BaseException:
            self.path.unlink(missing_ok=True)
            raise
        else:
            if kind is not None:
                self.path.unlink(missing_ok=True)
        finally:
            os.close(self.fd)


def atomic_output(path: str | os.PathLike[str], suffix: str = _SUFFIX, *, leftovers: bool = True) -> AtomicOutput:
    """An output written whole or not at all: a temporary file beside it, renamed over it when the ``with`` block ends.

    The temporary file is made (and locked) at once, as :func:`open` opens its file, so the
    call belongs in the ``with`` statement itself. When the block ends normally the file is
    synced and renamed over ``path`` (:func:`commit`); when it raises (an error, a cancel,
    :class:`KeyboardInterrupt`), or the rename fails, it is removed and the exception goes on.
    Its descriptor is closed either way.

    Parameters
    ----------
    path : path-like
        The output.
    suffix : str
        The end of the temporary file's name (:func:`temporary_file`).
    leftovers : bool
        Remove first what killed runs left beside ``path`` (:func:`remove_leftovers`).

    Returns
    -------
    AtomicOutput
        Its ``path`` is the temporary file to write (by name, or through its ``fd``).

    Raises
    ------
    OSError
        If no temporary file can be made beside ``path``.

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> with atomic_output(folder / "out.txt") as out:
    ...     _ = out.path.write_text("whole")
    >>> (folder / "out.txt").read_text(), sorted(p.name for p in folder.iterdir())
    ('whole', ['out.txt'])
    """
    return AtomicOutput(Path(path), suffix, leftovers)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder, synced, and a rename.

    Either ``path`` holds all of ``data`` afterwards, or it is as it was (and no temporary
    file is left: on an error, Ctrl+C or a SIGTERM the command line turns into an exception;
    a ``kill -9`` leaves one, which the next write of ``path`` by another process removes);
    an :class:`OSError` says why. The file gets the permissions a plain
    ``open(path, "wb")`` would give it: an existing file's, else ``0o666`` less the umask.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode & 0o7777
    except FileNotFoundError:
        mode = 0o666 & ~_UMASK
    with atomic_output(path, leftovers=os.path.abspath(path) not in _cleaned) as out:
        os.fchmod(out.fd, mode)
        view = memoryview(data)
        while view:
            view = view[os.write(out.fd, view) :]


def remove_leftovers(*paths: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files killed runs left beside these outputs; never another file, nor one a live run writes.

    A leftover is named as :func:`temporary_file` names the files of ``path`` (``.NAME.``,
    eight characters, ``.tmp`` or ``.part``), is a regular file, and is not locked: a run
    still writing it holds its lock, a run that died (``kill -9``, a power loss, a Dask
    worker lost) does not. Each folder is listed once, however many of its outputs are given.

    Parameters
    ----------
    *paths : path-like
        Outputs about to be written.

    Returns
    -------
    list of Path
        The files removed.
    """
    folders: dict[Path, set[str]] = {}
    if len(_cleaned) > _CLEANED_MAX:
        _cleaned.clear()
    for p in map(Path, paths):
        folders.setdefault(p.parent, set()).add(p.name)
        _cleaned.add(os.path.abspath(p))
    removed = []
    for folder, names in folders.items():
        try:
            entries = os.listdir(folder)
        except OSError:  # no folder (yet), or not ours to read: nothing of ours there
            continue
        for entry in entries:
            found = _OURS.fullmatch(entry) if entry.startswith(".") else None  # most names are not hidden: quicker
            if found is not None and found["name"] in names and _remove_if_left(folder / entry):
                removed.append(folder / entry)
    return removed


def _remove_if_left(path: Path) -> bool:
    """Remove ``path`` if it is a regular file no process holds locked; whether it was removed."""
    try:  # not followed if a link, not waited on if a FIFO
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return False
    try:
        found = os.fstat(fd)
        if not stat.S_ISREG(found.st_mode):
            return False
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # held: a live run's file (or no locks here: left alone)
        now = os.stat(path, follow_symlinks=False)
        if (now.st_dev, now.st_ino) != (found.st_dev, found.st_ino):
            return False  # another file under that name since it was opened
        path.unlink()
        return True
    except OSError:
        return False
    finally:
        os.close(fd)
