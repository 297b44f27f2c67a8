"""The autosave of an editing session: where it goes, what it restores, and the file each editor holds as its own.

An editor writes its autosave only while the file is its own: it holds an exclusive lock
(flock) on it, which the system lets go of when the editor's process ends however it ends
(no stale lock to clean up), and it writes over the file only if the file is still the one
it last read or wrote. Otherwise (another kernel's editor has the file, or wrote it since)
the editor autosaves to a file of its own, ``room.jpg.2.omniwidget-autosave.json``: no
editor ever writes over another's handles. Editors of one kernel are one person's: a newer
one (a cell run again) takes the file over, and the older keeps its handles apart.
"""

from __future__ import annotations

import errno
import hashlib
import os
import re
import threading
import time
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import require_regular_file
from .._files import atomic_write_bytes
from ..document.handles import Handles, load_handles
from ..errors import HandlesError, NotRegularFileError
from ._places import signature, writable_folder
from .status import Board, exception_text

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

__all__ = ["AUTOSAVE_ENV", "AUTOSAVE_SUFFIX", "Autosave", "autosave_location"]

#: The autosave file's name ends so: ``room.jpg.omniwidget-autosave.json`` next to ``room.jpg``.
AUTOSAVE_SUFFIX = ".omniwidget-autosave.json"
#: Set to ``0`` (or ``off``, ``false``, ``no``) to turn autosave off where not asked for explicitly.
AUTOSAVE_ENV = "OMNIWIDGET_AUTOSAVE"

#: The editors of this process holding an autosave file, by its absolute path.
_HOLDERS: weakref.WeakValueDictionary[str, Autosave] = weakref.WeakValueDictionary()
_HOLDERS_LOCK = threading.RLock()  # taken before any session's own lock
_MAX_NUMBER = 10_000  # room.jpg.2.omniwidget-autosave.json to room.jpg.9999.omniwidget-autosave.json


# --- where -------------------------------------------------------------------------------------
def _digest(data: bytes | memoryview) -> str:
    return hashlib.blake2b(data, digest_size=6).hexdigest()


def _autosave_name(image_path: Path | None, image: NDArray) -> str:
    """The autosave's name away from the image: the image's name and a digest of its path, or of an array's pixels."""
    if image_path is not None:
        return f"{image_path.stem}-{_digest(str(image_path.resolve()).encode())}{AUTOSAVE_SUFFIX}"
    pixels = np.ascontiguousarray(image)
    header = f"{pixels.shape}{pixels.dtype.str}".encode()
    return f"panorama-{_digest(header + _digest(pixels.data.cast('B')).encode())}{AUTOSAVE_SUFFIX}"


def autosave_location(autosave: Any, image_path: Path | None, image: NDArray) -> Path | None:
    """Where the editor of this image autosaves its handles, or None when it does not (see :class:`omniwidget.Editor`)."""
    if autosave is None:
        off = os.environ.get(AUTOSAVE_ENV, "").strip().lower() in ("0", "off", "false", "no")
        autosave = not off
    if isinstance(autosave, bool):
        if not autosave:
            return None
        if image_path is not None and writable_folder(image_path):
            return image_path.with_name(image_path.name + AUTOSAVE_SUFFIX)
        return Path.cwd() / _autosave_name(image_path, image)
    if not isinstance(autosave, (str, os.PathLike)):
        raise TypeError(f"autosave must be True, False or a path (a file or a folder), got {type(autosave).__name__}")
    path = Path(autosave)
    if path.is_dir():
        return path / _autosave_name(image_path, image)
    if not path.parent.is_dir():
        raise ValueError(f"autosave: the folder {path.parent} does not exist")
    return path


def _aside(path: Path) -> Path:
    """A free name next to ``path`` to keep an unreadable autosave under: ``<name>.bad``, ``<name>.2.bad``, ..."""
    candidate, n = path.with_name(path.name + ".bad"), 1
    while candidate.exists() or candidate.is_symlink():
        n += 1
        candidate = path.with_name(f"{path.name}.{n}.bad")
    return candidate


def _read_autosave(path: Path) -> tuple[Handles | None, str]:
    """The autosave's document (None when there is none or it is unreadable) and, when unreadable, why."""
    if not (path.exists() or path.is_symlink()):
        return None, ""
    try:
        return load_handles(path), ""
    except HandlesError as exc:
        problem = str(exc)
    except Exception as exc:  # noqa: BLE001 - whatever is wrong with the file, the editor opens
        problem = f"{path}: {type(exc).__name__}: {exc}"
    return None, problem


# --- each file is one editor's -----------------------------------------------------------------
def _path_key(path: Path) -> str:
    """The name an autosave file goes by in :data:`_HOLDERS`: its absolute path, links resolved."""
    return str(path.resolve())


def _split(name: str) -> tuple[str, str]:
    """An autosave's name cut where an editor's number goes: ``("room.jpg", AUTOSAVE_SUFFIX)``, ``("mine", ".json")``."""
    if name.endswith(AUTOSAVE_SUFFIX) and name != AUTOSAVE_SUFFIX:
        return name[: -len(AUTOSAVE_SUFFIX)], AUTOSAVE_SUFFIX
    stem, dot, ext = name.rpartition(".")
    return (stem, dot + ext) if stem else (name, "")


def _numbered(path: Path, n: int) -> Path:
    """Editor ``n``'s own autosave beside ``path``: ``room.jpg.2.omniwidget-autosave.json``, ``mine.2.json``."""
    head, tail = _split(path.name)
    return path.with_name(f"{head}.{n}{tail}")


def _autosave_files(path: Path) -> list[Path]:
    """``path`` and the editors' own autosaves beside it, those that are there, by number."""
    head, tail = _split(path.name)
    pattern = re.compile(re.escape(head) + r"\.([2-9]|[1-9]\d+)" + re.escape(tail))
    try:
        names = os.listdir(path.parent)
    except OSError:
        names = []
    numbered = sorted((int(m.group(1)), name) for name in names if (m := pattern.fullmatch(name)))
    return [path] * os.path.lexists(path) + [path.with_name(name) for _, name in numbered]


def _not_regular(path: Path) -> str:
    """Why the autosave ``path`` is never opened (a FIFO, a device, a socket: reading one may wait for ever), or ""."""
    if path.is_dir():
        return ""  # an unreadable autosave, kept aside at the first edit
    try:
        require_regular_file(path, "autosave")
    except NotRegularFileError as exc:
        return str(exc)
    return ""


class _Claim:
    """An exclusive lock (``flock``) on an autosave file, held while its editor lives: other editors see the file is in use."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def close(self) -> None:
        fd, self.fd = self.fd, -1
        if fd >= 0:
            os.close(fd)  # the lock goes with it

    __del__ = close


def _flock(fd: int, shared: bool = False) -> bool:
    """Lock ``fd`` without waiting; False when another open file holds a lock that excludes it."""
    if fcntl is None:  # pragma: no cover - Windows: no advisory locks; the check at write time remains
        return True
    try:
        fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # a file system without locks: the check at write time remains
        pass
    return True


def _lock(path: Path) -> _Claim | None:
    """Lock the regular file ``path`` for this editor (a few tries); None when another editor holds it."""
    for _ in range(20):  # another editor looking (a shared lock held for a moment) is waited for
        if not path.is_file():  # only a regular file is opened (a FIFO could block)
            return None
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        except OSError:
            return None
        if _flock(fd):
            return _Claim(fd)
        os.close(fd)
        time.sleep(0.005)
    return None


def _held_elsewhere(path: Path) -> bool:
    """Whether an editor of another process holds ``path`` (only a regular file is opened, for a moment)."""
    if fcntl is None or not path.is_file():
        return False
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        return not _flock(fd, shared=True)
    finally:
        os.close(fd)


def _in_use(path: Path) -> str:
    """Where an editor holds ``path``: "this kernel", "another kernel or program", or ""."""
    if _HOLDERS.get(_path_key(path)) is not None:
        return "this kernel"
    return "another kernel or program" if _held_elsewhere(path) else ""


def _create_numbered(path: Path, data: bytes) -> tuple[Path, _Claim]:
    """Write ``data`` to a new file beside ``path`` (the first free number) and lock it: an editor's own autosave."""
    for n in range(2, _MAX_NUMBER):
        candidate = _numbered(path, n)
        try:
            fd = os.open(candidate, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # never over anything, a FIFO included
        except FileExistsError:
            continue
        try:
            _flock(fd)  # a new file: no one else has it
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
        except BaseException:
            os.close(fd)
            candidate.unlink(missing_ok=True)
            raise
        return candidate, _Claim(fd)
    taken = f"{_numbered(path, 2).name} to {_numbered(path, _MAX_NUMBER - 1).name} are all taken"
    raise FileExistsError(errno.EEXIST, taken, str(path.parent))


def _mtime(path: Path) -> int:
    try:
        return os.stat(path).st_mtime_ns
    except OSError:
        return 0


def _count(doc: Handles) -> str:
    return f"{len(doc)} handle" if len(doc) == 1 else f"{len(doc)} handles"


# --- what an editor finds when it opens --------------------------------------------------------
@dataclass(frozen=True)
class _Found:
    """An autosave of the panorama as read at opening: its document (None when unreadable or none) and why not."""

    path: Path
    document: Handles | None
    problem: str
    special: bool  # no regular file (a FIFO, a device): never opened


def _find(home: Path) -> list[_Found]:
    """The panorama's autosaves at ``home`` and beside it, each read unless it is no regular file."""
    found = []
    for path in _autosave_files(home):
        refused = _not_regular(path)
        saved, problem = (None, refused) if refused else _read_autosave(path)
        found.append(_Found(path, saved, problem, bool(refused)))
    return found


def _file_notes(found: list[_Found], home: Path, target: Path, doc: Handles, given: bool) -> tuple[list[str], bool]:
    """What the notice says of each autosave found, and whether the one to write is unreadable (moved aside at the first edit)."""
    notes, bad = [], False
    where = _in_use(target)
    for f in found:
        if f.path == home and f.document is not None and len(f.document) and given and f.document != doc:
            fate = "it is kept" if where == "another kernel or program" else "the first edit replaces it"
            notes.append(f"the autosave {home} ({_count(f.document)}) is not used: handles were given; {fate}")
        elif f.path == target and f.problem and not f.special:
            bad = True
            aside = f"the file is kept, as {_aside(f.path).name} from the first edit"
            notes.append(
                f"the autosave is unreadable: {f.problem}; handles were given ({aside})"
                if given
                else f"could not restore the autosave: {f.problem}; opened with no handles ({aside})"
            )
        elif f.problem:
            own = ", and this editor autosaves to a file of its own" if f.path == target else ""
            notes.append(f"{f.problem}: it is left as it is{own}")
    return notes, bad


def _others_note(kept: list[tuple[Path, Handles]], others: list[Path]) -> list[str]:
    """The notice's word on the panorama's autosaves not restored, and who has them open."""
    if not others:
        return []
    names = []
    for p, d in kept:
        if p in others:
            holder = _in_use(p)
            names.append(f"{p.name} ({_count(d)}{f', open in {holder}' if holder else ''})")
    return [f"other autosaves of this panorama are kept: {', '.join(names)}; load() takes one"]


def _use_note(target: Path) -> list[str]:
    """The notice's word on another editor having the autosave open."""
    where = _in_use(target)
    if where == "this kernel":
        return [
            f"another editor of this panorama is open in this kernel: this one takes {target.name} over at its first edit, "
            "the other keeps its handles apart"
        ]
    if where:
        return [f"another editor (in {where}) has {target} open: this editor autosaves to a file of its own, so that neither erases the other's"]
    return []


class Autosave:
    """One editor's autosave: the file it writes while it is its own, else a file of its own beside it.

    Parameters
    ----------
    path : Path
        The panorama's autosave (:func:`autosave_location`).
    board : Board
        The editor's board: its handles are written when a newer editor of this kernel
        takes the file over, and the notice is shown in its status (``status["notice"]``).
    """

    def __init__(self, path: Path, board: Board) -> None:
        self.path = path  # where it writes
        self.home = path  # the panorama's first autosave name; an editor's own ones are numbered beside it
        self.other_autosaves: list[Path] = []  # this panorama's autosaves not restored, offered in the notice
        self.notice = ""
        self.restored: dict | None = None  # the document restored
        self._board = board
        self._bad = False  # the autosave file is unreadable: moved aside at the first edit
        self._claim: _Claim | None = None  # the lock on path, from the first autosave on
        self._seen: tuple[int, ...] | None = None  # path's signature when this editor last read or wrote it
        self._divert = ""  # why the next autosave goes to a file of this editor's own
        self._own = ""  # the notice of an editor autosaving to a file of its own

    def open(self, doc: Handles, given: bool) -> Handles | None:
        """Read this panorama's autosaves; return the document restored (None when none is).

        Without given handles the newest autosave with handles is restored, and the file it
        came from is the one this editor goes on writing (while it is its own); the others are
        offered in the notice and :attr:`other_autosaves`. A FIFO or device is never opened.
        """
        home = self.home
        found = _find(home)
        kept = sorted(((f.path, f.document) for f in found if f.document is not None and len(f.document)), key=lambda f: _mtime(f[0]), reverse=True)
        target, notes, restored = home, [], None
        if kept and not given:
            target, restored = kept[0]
            self.restored = restored.to_dict()
            notes.append(f"restored {_count(restored)} from {target} (undo to start without them)")
        file_notes, self._bad = _file_notes(found, home, target, doc if restored is None else restored, given)
        notes += file_notes
        self.other_autosaves = [p for p, _ in kept if p != target and not (given and p == home)]
        notes += _others_note(kept, self.other_autosaves) + _use_note(target)
        self.path, self._seen = target, signature(target)
        self.notice = "; ".join(notes)
        return restored

    def write(self, doc: Handles) -> None:
        """Write ``doc`` (whole or not at all) while the file is this editor's, else a file of its own; a failure is said, never raised."""
        try:
            with _HOLDERS_LOCK:
                notice = self._write((doc.to_json() + "\n").encode())
        except Exception as exc:  # noqa: BLE001 - the edit stands; the person is told it is not on disk
            notice = self._failed(exc)
        self._say(notice)

    def _failed(self, exc: BaseException) -> str:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exception_text(exc)
        return f"could not autosave to {self.path} ({reason}): these handles are not on disk; Save or Download them"

    def _say(self, notice: str) -> None:
        if notice != self.notice:
            self.notice = notice
            with self._board.lock:
                self._board.set_status(notice=notice)

    def _write(self, data: bytes) -> str:
        """Write ``data`` to the autosave if it is still this editor's, else to a new file of its own; return the notice."""
        path = self.path
        why = self._divert or self._not_mine(path)
        if why:
            return self._write_own(data, why)
        notice = self._own
        if self._bad:
            bad = _aside(path)
            if os.path.lexists(path):
                os.replace(path, bad)
            self._bad = False
            notice = f"the unreadable autosave was kept as {bad}"
        atomic_write_bytes(path, data)
        self._seen = signature(path)
        self._hold(path, _lock(path))
        return notice

    def _not_mine(self, path: Path) -> str:
        """Why this editor must not write over ``path`` (another editor's file, or not a regular one), or "".

        An older editor of this kernel holding it hands it over (:meth:`hand_over`).
        """
        refused = _not_regular(path)
        if refused:
            return f"{refused}; it is left as it is"
        holder = _HOLDERS.get(_path_key(path))
        if holder is not None and holder is not self:
            holder.hand_over(self)
            return ""
        if holder is None and _held_elsewhere(path):
            return f"another editor (in another kernel or program) has {path} open"
        if signature(path) != self._seen:
            return f"{path} was written by another editor since this one {'wrote' if holder is self else 'opened'} it"
        return ""

    def _write_own(self, data: bytes, why: str) -> str:
        """Write ``data`` to a new file beside the autosave, this editor's own from now on; return the notice saying why."""
        path, claim = _create_numbered(self.home, data)
        self.release()
        self.path, self._seen, self._divert, self._bad = path, signature(path), "", False
        self._hold(path, claim)
        self._own = f"{why}; this editor's handles are autosaved to {path} instead (no editor writes over another's)"
        return self._own

    def _hold(self, path: Path, claim: _Claim | None) -> None:
        """Make ``path`` (locked by ``claim``, if it could be) this editor's autosave."""
        old, self._claim = self._claim, claim
        if old is not None:
            old.close()
        _HOLDERS[_path_key(path)] = self

    def release(self) -> None:
        """Let go of the autosave file (the file stays): another editor may take it."""
        with _HOLDERS_LOCK:
            if _HOLDERS.get(_path_key(self.path)) is self:
                del _HOLDERS[_path_key(self.path)]
            if self._claim is not None:
                self._claim.close()
                self._claim = None

    def hand_over(self, newer: Autosave) -> None:
        """Give the autosave to a newer editor of this panorama in this kernel (a cell run again); keep these handles apart.

        Handles the newer editor did not start from are written at once to a file of this
        editor's own; otherwise its next edit goes to one.
        """
        why = f"a newer editor of this panorama in this kernel took over {self.path}"
        self.release()
        try:
            handles = self._board.handles
            doc = Handles.from_dict(handles)
            if len(doc) and handles != newer.restored:
                notice = self._write_own((doc.to_json() + "\n").encode(), why)
            else:
                self._divert = why
                notice = f"{why}; this editor's next edit is autosaved to a file of its own"
        except Exception as exc:  # noqa: BLE001 - the newer editor goes on; this one says its handles are not on disk
            notice = self._failed(exc)
        self._say(notice)
