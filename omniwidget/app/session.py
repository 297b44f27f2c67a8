"""An editing session: a panorama, its handles, undo and redo, autosave and the newest result, in plain Python.

:class:`EditingSession` is everything the notebook editor (:class:`omniwidget.Editor`) does
apart from the widget: the handles document and its history (undo, redo), the autosave
file, the preview computed in a worker thread after every edit (only the newest edit's
result is ever shown), the status line, Save image, the live drag's basis, and the commands
the front end sends. The widget only syncs its traits with it and passes messages; tests and
scripts drive a session without anywidget. Suggested lines and levelling
(:mod:`omniwidget.detect`) run in workers of their own: the suggestions are shown until
accepted (each an undoable edit) or dropped, and the level rotation is one undoable edit.

A session tells whoever shows it what changed through ``on_change(changes)`` (a dict of the
fields that changed: ``handles``, ``history``, ``status``, ``preview``, ``folds``,
``outputs``, ``suggestions``; called from the worker threads for results) and sends the
front end messages through ``on_message(content, buffers)``.
"""

from __future__ import annotations

import atexit
import errno
import hashlib
import json
import os
import re
import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import require_regular_file, whole_number
from .._files import atomic_write_bytes
from ..document.handles import CageHandle, Handles, LineHandle, Options, PointHandle, load_handles, save_handles
from ..errors import HandlesError, ImageError, NotRegularFileError, OmniwidgetError, VideoError
from ..io.draw import display_rgb
from ..io.images import check_format, check_panorama, image_header, read_image, write_image
from ..io.metadata import Metadata, output_metadata, read_metadata
from ..sphere import coords
from ._latest import Latest

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

if TYPE_CHECKING:
    from ..detect import Suggestion
    from ..io.video import VideoReader, VideoReport
    from ..method.constraints import Constraints
    from ..raster.pipeline import Result

__all__ = [
    "AUTOSAVE_SUFFIX",
    "DISPLAY_WIDTH",
    "HISTORY",
    "LAZY_WIDTH",
    "PREVIEW_WIDTH",
    "RESULT_SUFFIX",
    "EditingSession",
    "as_document",
]

#: Width of the result computed after every edit (the issue's "about 1024 x 512").
PREVIEW_WIDTH = 1024
#: Largest width of the panorama sent to the browser; larger panoramas are sent downscaled.
DISPLAY_WIDTH = 2048
#: A JPEG panorama wider than this is opened reduced (decoded at 1/2 to 1/8 by libjpeg, at
#: least as wide as the display, the preview's source and the detector need): its full size
#: is read only when a full-size result is asked for (Save image, ``full=True``).
LAZY_WIDTH = 8192
#: Edits kept for undo.
HISTORY = 500
#: Seconds a result stays on screen before its quality figures are measured (a drag may go on).
QUALITY_DELAY = 0.3
#: The autosave file's name ends so: ``room.jpg.omniwidget-autosave.json`` next to ``room.jpg``.
AUTOSAVE_SUFFIX = ".omniwidget-autosave.json"
#: Set to ``0`` (or ``off``, ``false``, ``no``) to turn autosave off where not asked for explicitly.
AUTOSAVE_ENV = "OMNIWIDGET_AUTOSAVE"
#: Save image names the full-size result so: ``room-rectified.jpg`` next to ``room.jpg``.
RESULT_SUFFIX = "-rectified"
#: Formats tried, in order, after the input's own when it cannot hold the result.
_RESULT_FORMATS = (".png", ".tif", ".npy")
_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".tif": "image/tiff", ".tiff": "image/tiff", ".webp": "image/webp", ".bmp": "image/bmp"}

_PACKAGE = Path(__file__).resolve().parents[1]  # the package, never written to (the bundled sample lives in it)
_HANDLE_NAME = re.compile(r"handles\[(\d+)\]")


def as_document(value: Any) -> Handles:
    """A handles document from a :class:`Handles`, its JSON-ready dict or its JSON text (validated)."""
    if isinstance(value, Handles):
        return value
    if isinstance(value, (str, bytes)):
        return Handles.from_json(value)
    return Handles.from_dict(value)


def _display_rgb8(image: NDArray, width: int) -> NDArray[np.uint8]:
    """An RGB uint8 copy of ``image`` at most ``width`` wide, for the browser."""
    import cv2

    if image.shape[1] > width:
        image = cv2.resize(image, (width, width // 2), interpolation=cv2.INTER_AREA)
    return display_rgb(image)


def _jpeg(rgb: NDArray[np.uint8], quality: int = 90) -> bytes:
    import cv2

    ok, data = cv2.imencode(".jpg", rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 RGB image
        raise ImageError("could not encode the image for display")
    return data.tobytes()


def _fold_overlay(mask: NDArray[np.bool_]) -> bytes:
    """A PNG, transparent but where the output folds over (magenta), or b"" when it does not."""
    import cv2

    if not mask.any():
        return b""
    rgba = np.zeros(mask.shape + (4,), np.uint8)
    rgba[mask] = (255, 0, 255, 150)  # BGRA: magenta
    ok, data = cv2.imencode(".png", rgba)
    return data.tobytes() if ok else b""


def _output_points(doc: Handles, constraints: Constraints) -> list[list[list[float]]]:
    """For each handle, where its control points go in the output, ``[lon, lat]``.

    A point: centre, east and west arrow tips. A line: start, middle, end, placed by the
    rectify-all solve when the document asks for it (a line split at a crossing takes each
    control point from the piece nearest to it). A cage: its vertices' targets.
    """
    pieces: dict[int, list[tuple[Any, NDArray]]] = {}
    for index, samples in constraints.lines:
        control = constraints.controls[index]
        pieces.setdefault(control.handle, []).append((control.moebius, coords.lonlat_to_xyz(samples)))
    out = []
    for i, h in enumerate(doc.handles):
        if isinstance(h, PointHandle):
            points = h.target_points()
        elif isinstance(h, LineHandle):
            points = h.control_points()
            if i in pieces:
                for k, p in enumerate(coords.lonlat_to_xyz(points)):
                    reach = [float((piece[1] @ p).max()) for piece in pieces[i]]
                    nearest = pieces[i][reach.index(max(reach))]  # the first piece that comes nearest
                    points[k] = nearest[0](points[k])
        else:
            points = np.asarray(h.finals, float)
        out.append([[round(float(lon), 9), round(float(lat), 9)] for lon, lat in points])
    return out


def _reset(h: PointHandle | LineHandle | CageHandle) -> PointHandle | LineHandle | CageHandle:
    """The handle as drawn, before any transformation."""
    if isinstance(h, PointHandle):
        return replace(h, target=None, rotation=0.0, scale=1.0)
    if isinstance(h, LineHandle):
        return replace(h, rectify=False, targets=None)
    return replace(h, targets=None)


# --- autosave ----------------------------------------------------------------------------------
def _digest(data: bytes | memoryview) -> str:
    return hashlib.blake2b(data, digest_size=6).hexdigest()


def _open(path: Path, preview_width: int) -> tuple[NDArray, int]:
    """The panorama at ``path`` and its reduction: one wider than :data:`LAZY_WIDTH` decoded reduced to what the editor shows."""
    from ..detect import DETECT_WIDTH
    from ..io.large import plan_read

    header = image_header(path)
    if header is not None and max(header.width, header.height) > LAZY_WIDTH:
        needed = max(DISPLAY_WIDTH, 2 * preview_width, DETECT_WIDTH)
        reduced = plan_read(header, needed).reduce  # a JPEG by libjpeg; another format above STREAM_BYTES in strips
        if reduced > 1:
            return read_image(path, width=needed), reduced
    return read_image(path), 1


def _autosave_name(image_path: Path | None, image: NDArray) -> str:
    """The autosave's name away from the image: the image's name and a digest of its path, or of an array's pixels."""
    if image_path is not None:
        return f"{image_path.stem}-{_digest(str(image_path.resolve()).encode())}{AUTOSAVE_SUFFIX}"
    pixels = np.ascontiguousarray(image)
    header = f"{pixels.shape}{pixels.dtype.str}".encode()
    return f"panorama-{_digest(header + _digest(pixels.data.cast('B')).encode())}{AUTOSAVE_SUFFIX}"


def _writable_folder(image_path: Path) -> bool:
    """Whether the editor writes next to ``image_path``: a folder it may write to, and not the package's (the bundled sample)."""
    folder = image_path.resolve().parent
    return not folder.is_relative_to(_PACKAGE) and os.access(folder, os.W_OK | os.X_OK)


def _autosave_location(autosave: Any, image_path: Path | None, image: NDArray) -> Path | None:
    """Where the editor of this image autosaves its handles, or None when it does not (see :class:`omniwidget.Editor`)."""
    if autosave is None:
        off = os.environ.get(AUTOSAVE_ENV, "").strip().lower() in ("0", "off", "false", "no")
        autosave = not off
    if isinstance(autosave, bool):
        if not autosave:
            return None
        if image_path is not None and _writable_folder(image_path):
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


# --- autosave: each file is one editor's ----------------------------------------------------------
# An editor writes its autosave only while the file is its own: it holds an exclusive lock
# (flock) on it, which the system lets go of when the editor's process ends however it ends
# (no stale lock to clean up), and it writes over the file only if the file is still the one
# it last read or wrote. Otherwise (another kernel's editor has the file, or wrote it since)
# the editor autosaves to a file of its own, ``room.jpg.2.omniwidget-autosave.json``: no
# editor ever writes over another's handles. Editors of one kernel are one person's: a newer
# one (a cell run again) takes the file over, and the older keeps its handles apart.
#: The editors of this process holding an autosave file, by its absolute path.
_HOLDERS: weakref.WeakValueDictionary[str, EditingSession] = weakref.WeakValueDictionary()
_HOLDERS_LOCK = threading.RLock()  # taken before any session's own lock
_MAX_NUMBER = 10_000  # room.jpg.2.omniwidget-autosave.json to room.jpg.9999.omniwidget-autosave.json


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


def _signature(path: Path) -> tuple[int, ...] | None:
    """The file's device, inode, size and time of change (None when there is none): what tells one version from the next."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


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


def _handles_location(image_path: Path | None) -> tuple[Path, bool]:
    """Where Save writes the handles by default, and whether that name is the image's stem in the working folder only.

    ``day1/room.handles.json`` for ``day1/room.jpg`` (next to it, as Save image writes); for an
    array, the bundled sample or an image in a folder not to write to, ``<stem>.handles.json``
    in the working folder, a name other panoramas may share.
    """
    if image_path is not None and _writable_folder(image_path):
        return image_path.with_name(f"{image_path.stem}.handles.json"), False
    stem = image_path.stem if image_path is not None else "panorama"
    return Path(f"{stem}.handles.json"), True


# --- save image --------------------------------------------------------------------------------
def _result_location(image_path: Path | None, result: NDArray) -> Path:
    """Where Save image writes ``result``: see :meth:`EditingSession.save_image`."""
    suffixes: tuple[str, ...]
    if image_path is None:
        base, suffixes = Path.cwd() / f"panorama{RESULT_SUFFIX}", _RESULT_FORMATS
    else:
        folder = image_path.parent
        if image_path.resolve().parent.is_relative_to(_PACKAGE):  # the bundled sample: never written next to it
            folder = Path.cwd()
        base, suffixes = folder / f"{image_path.stem}{RESULT_SUFFIX}", (image_path.suffix, *_RESULT_FORMATS)
    for suffix in suffixes:
        candidate = base.with_name(base.name + suffix)
        try:
            check_format(candidate, result)
        except ImageError:
            continue  # this format cannot hold the result (alpha in a JPEG, a float image in a PNG, ...)
        return candidate
    return base.with_name(base.name + ".npy")  # pragma: no cover - .npy holds any array


# --- videos ------------------------------------------------------------------------------------
def _frame_index(video: VideoReader, frame: Any, seconds: Any) -> int:
    """The frame chosen by its index (``frame``) or by its time (``seconds`` from the video's start); 0 by default."""
    count = len(video)
    if frame is not None and seconds is not None:
        raise TypeError("give frame (an index) or time (seconds), not both")
    if seconds is not None:
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float, np.integer, np.floating)) or not np.isfinite(seconds):
            raise TypeError(f"time must be a number of seconds, got {seconds!r}")
        if not 0 <= seconds < count * video.frame_interval:
            raise ValueError(f"time {seconds} s: the video is {count * video.frame_interval:.3f} s long ({count} frames)")
        return min(count - 1, int(np.floor(float(seconds) / video.frame_interval + 1e-6)))
    if frame is None:
        return 0
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise TypeError(f"frame must be a frame index (an int; time= takes seconds), got {frame!r}")
    if not 0 <= frame < count:
        raise IndexError(f"frame {frame}: the video has {count} frames (0 to {count - 1})")
    return int(frame)


def _video_location(video_path: Path) -> Path:
    """Where Save video writes: ``clip.mp4`` gives ``clip-rectified.mp4`` next to it (MP4 for inputs in other containers)."""
    from ..io.video import OUTPUT_SUFFIXES

    suffix = video_path.suffix if video_path.suffix.lower() in OUTPUT_SUFFIXES else ".mp4"
    return video_path.with_name(f"{video_path.stem}{RESULT_SUFFIX}{suffix}")


#: Save video's threads running, each with its cancel: stopped when the interpreter exits.
_VIDEO_JOBS: set[tuple[threading.Thread, threading.Event]] = set()


@atexit.register
def _cancel_video_jobs() -> None:
    """Cancel every video being saved and let it clean up (its temporary file) before the interpreter finalizes."""
    for job, cancel in list(_VIDEO_JOBS):
        cancel.set()
        job.join(10.0)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def _exception_text(exc: BaseException) -> str:
    """``Name: message`` of an exception, readable when the message is empty (a bare MemoryError, say)."""
    name = type(exc).__name__
    try:
        detail = str(exc).strip()
    except Exception:  # noqa: BLE001 - a broken __str__ must not hide the error itself
        detail = ""
    if not detail and isinstance(exc, MemoryError):
        detail = "out of memory"
    return f"{name}: {detail}" if detail else name


def _line_key(start: Any, end: Any) -> tuple[float, ...]:
    """A line's ends, to 1e-6 degrees and in either order: a suggestion and the handle accepted from it match."""
    a, b = (tuple(round(float(v), 6) for v in p) for p in (start, end))
    return (*min(a, b), *max(a, b))


def _count(doc: Handles) -> str:
    return f"{len(doc)} handle" if len(doc) == 1 else f"{len(doc)} handles"


def _reaches(handles: Any) -> list[float | None]:
    """Per handle, a point's reach in degrees (its ``reach``, or the default the method takes), None for the others.

    The editor draws it as the ring round a selected point (:mod:`omniwidget.method.reach`).
    """
    from ..document.handles import PointHandle
    from ..method.reach import default_reach

    return [
        (h.reach if h.reach is not None else default_reach(handles, i)) if isinstance(h, PointHandle) else None
        for i, h in enumerate(handles.handles)
    ]


def _kept_lines(result: Any) -> list[int]:
    """Rectified lines over or close to a pole that the still background keeps as they are (identity map)."""
    if result.handles.options.anchor is None:
        return []  # the paper's method rectifies them all the same (and warns: a conflict)
    return sorted(int(i) for i, _ in result.constraints.near_pole)


def _warning_kinds(result: Any) -> list[str]:
    """Per warning of ``result``, what it is about (:attr:`omniwidget.raster.pipeline.Result.warning_kinds`): the editor's groups."""
    kinds = list(getattr(result, "warning_kinds", ()))
    return kinds if len(kinds) == len(result.warnings) else ["conflicts"] * len(result.warnings)


def _finite_outputs(outputs: list[list[list[float]]]) -> bool:
    return all(np.isfinite(points).all() for points in outputs if points)



Changes = dict[str, Any]


class EditingSession:
    """A panorama being edited: its handles, their history, the autosave and the newest result.

    Parameters are those of :class:`omniwidget.Editor` (``image``, ``handles``,
    ``preview_width``, ``handles_path``, ``autosave``, ``quality``), and:

    frame, time : int, float, optional
        For a video file (:func:`~omniwidget.io.video.is_video_path`): the frame shown, by
        index or by seconds from the start (default: the first); see :meth:`set_frame` and
        :meth:`save_video`.
    on_change : callable, optional
        ``on_change(changes)`` with a dict of the fields that changed (``handles``,
        ``history``, ``status``, ``preview``, ``folds``, ``outputs``; for a video ``frame``
        and ``source``, the new frame as :meth:`display_source` gives it); results arrive
        from the worker thread, Save video's progress from its own.
    on_message : callable, optional
        ``on_message(content, buffers)``: a message for the front end (a command done, the
        live drag's basis, an image file to download).

    Nothing is computed until :meth:`start`, so that the widget can sync its traits first.

    The autosave is this session's while it holds it (see :class:`omniwidget.Editor`'s
    ``autosave``): :attr:`autosave_path` is where it writes, which becomes a file of its own
    (``room.jpg.2.omniwidget-autosave.json``) when another editor has the panorama's file;
    :attr:`other_autosaves` lists the panorama's autosaves it did not restore, and
    :meth:`close` lets go of the file.
    """

    def __init__(
        self,
        image: NDArray | str | os.PathLike[str],
        handles: Handles | dict | str | os.PathLike[str] | None = None,
        *,
        preview_width: int = PREVIEW_WIDTH,
        handles_path: str | os.PathLike[str] | None = None,
        autosave: bool | str | os.PathLike[str] | None = None,
        quality: bool = True,
        frame: int | None = None,
        time: float | None = None,
        on_change: Callable[[Changes], None] | None = None,
        on_message: Callable[[dict, list], None] | None = None,
    ) -> None:
        self._video: VideoReader | None = None
        self.frame = 0
        self._reduced = 1  # the working copy is 1 / _reduced of the panorama's size (_open)
        if isinstance(image, (str, os.PathLike)):
            self._image_path: Path | None = Path(image)
            from ..io.video import VideoReader, is_video_path

            if is_video_path(image):
                self._video = VideoReader(image)
                self.frame = _frame_index(self._video, frame, time)
                image = self._video.read(self.frame)
            else:
                image, self._reduced = _open(Path(image), whole_number(preview_width, "preview_width", minimum=2, even=True))
        else:
            self._image_path = None
        if self._video is None and (frame is not None or time is not None):
            raise TypeError("frame and time choose a frame of a video; the editor was given an image")
        self._working = check_panorama(image)  # the panorama, or a JPEG's reduced decoding (self._reduced)
        self._working.flags.writeable = False
        self._full_image: NDArray | None = self._working if self._reduced == 1 else None
        self._scaled: dict[int, NDArray] = {}
        width = self._working.shape[1] * self._reduced
        self._width = width
        preview_width = whole_number(preview_width, "preview_width", minimum=2, even=True)
        self._preview_width = min(preview_width, width)
        self._preview_source = self._downscaled(2 * self._preview_width)
        self._default_handles, shared_name = _handles_location(self._image_path)
        self.handles_path = Path(handles_path) if handles_path is not None else self._default_handles
        self._guard_handles = handles_path is None and shared_name  # Save replaces only a file of its own there
        self._handles_written: tuple[int, ...] | None = None  # the handles file as this editor last saved or read it
        self._on_change = on_change or (lambda changes: None)
        self._on_message = on_message or (lambda content, buffers: None)
        self._lock = threading.Lock()
        self._generation = 0
        self._worker = Latest("omniwidget-editor")
        self._quality = Latest("omniwidget-editor-quality")
        self._live = Latest("omniwidget-editor-live")
        # suggested lines and levelling, each in a worker of its own: never in the preview's way, nor one in the other's
        self._suggest_worker = Latest("omniwidget-editor-suggest")
        self._level_worker = Latest("omniwidget-editor-level")
        self._straighten_worker = Latest("omniwidget-editor-straighten")
        self._measure = bool(quality)
        self._undo: list[dict] = []
        self._redo: list[dict] = []
        self._preview_result: Result | None = None  # the Result on screen
        self._full_result: tuple[str, Result] | None = None
        self.last_error: BaseException | None = None
        self.status: dict = {}
        self.preview = b""
        self.folds = b""
        self.outputs: list = []
        self.autosave_path = _autosave_location(autosave, self._image_path, self._working)
        self.other_autosaves: list[Path] = []  # this panorama's autosaves not restored, offered in the notice
        self._notice = ""  # status["notice"]
        self._autosave_bad = False  # the autosave file is unreadable: moved aside at the first edit
        self._claim: _Claim | None = None  # the lock on autosave_path, from the first autosave on
        self._seen: tuple[int, ...] | None = None  # autosave_path's signature when this editor last read or wrote it
        self._restored: dict | None = None  # the document restored from it
        self._home = self.autosave_path  # the panorama's first autosave name; an editor's own ones are numbered beside it
        self._divert = ""  # why the next autosave goes to a file of this editor's own
        self._own = ""  # the notice of an editor autosaving to a file of its own
        if isinstance(handles, (str, os.PathLike)) and not str(handles).lstrip().startswith("{"):
            handles_file: Path | None = Path(handles)
            handles = load_handles(handles)
        else:
            handles_file = None
        doc = Handles() if handles is None else as_document(handles)
        if self.autosave_path is not None:
            doc = self._open_autosave(self.autosave_path, doc, given=handles is not None)
        self.handles: dict = doc.to_dict()
        if handles_file is not None:
            self._note_handles_file(handles_file)
        self.history = {"undo": len(self._undo), "redo": len(self._redo)}
        self._video_job: threading.Thread | None = None
        self._video_cancel: threading.Event | None = None
        self._video_error: BaseException | None = None
        self._video_report: VideoReport | None = None
        self._suggested: list[Suggestion] = []  # the last suggest_lines, best first; shown unless accepted or dropped
        self._dropped: set[int] = set()
        self.suggestions: list[dict] = []
        self._levelling = False
        self._straightening = False
        self._detect_errors: dict[str, BaseException | None] = {"suggest": None, "level": None, "straighten": None}  # for wait=True

    def start(self) -> None:
        """Compute the first result (in the worker)."""
        self._changed(self.document)

    def _publish(self, **changes: Any) -> None:
        """Set the fields and tell ``on_change``."""
        for name, value in changes.items():
            setattr(self, name, value)
        self._on_change(changes)

    def _set_status(self, **fields: Any) -> None:
        self._publish(status={**self.status, **fields})

    def _clear_finished(self) -> None:
        """An edit begins: the messages of the jobs that ended (Level, Save, Suggest lines that found none) go.

        A job still running keeps its message; Suggest lines' prompt stays while suggestions
        are shown (:meth:`_show_suggestions` says how many are left).
        """
        with self._lock:
            cleared = {}
            for job in ("level", "save", "suggest", "straighten"):
                fields = self.status.get(job)
                if not fields or fields.get("state") == "running" or not fields.get("message"):
                    continue
                if job == "suggest" and fields.get("state") == "done" and self.suggestions:
                    continue
                cleared[job] = {**fields, "message": ""}
            if cleared:
                self._set_status(**cleared)

    def _set_save(self, state: str, message: str) -> None:
        """``status["save"]``: Save's and Save image's ``state`` ("running", "done" or "error") and ``message``."""
        with self._lock:
            self._set_status(save={"state": state, "message": message})

    # --- the image -----------------------------------------------------------------------
    @property
    def image(self) -> NDArray:
        """The input panorama at full size (read-only); a panorama opened reduced is read whole at the first ask."""
        if self._full_image is None:
            if self._image_path is None:  # pragma: no cover - only files are opened reduced
                raise ImageError("the panorama's full size is not known")
            image = check_panorama(read_image(self._image_path), str(self._image_path))
            if image.shape[1] != self._width:
                raise ImageError(f"{self._image_path}: the file changed while it was edited ({image.shape[1]} wide, opened {self._width})")
            image.flags.writeable = False
            self._full_image = image
        return self._full_image

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)`` of the panorama at full size (known before it is read whole)."""
        return self._width, self._width // 2

    @property
    def image_path(self) -> Path | None:
        """The file the panorama was read from, None for an array."""
        return self._image_path

    def _downscaled(self, width: int) -> NDArray:
        """The panorama at most ``width`` wide, made once per width (display and preview share 2048)."""
        import cv2

        width = min(width, self._width)
        if width not in self._scaled:
            source = self._working if self._working.shape[1] >= width else self.image
            small = source if width == source.shape[1] else cv2.resize(source, (width, width // 2), interpolation=cv2.INTER_AREA)
            self._scaled[width] = small
        return self._scaled[width]

    def display_source(self) -> bytes:
        """The panorama as the browser shows it: a JPEG at most :data:`DISPLAY_WIDTH` wide."""
        return _jpeg(display_rgb(self._downscaled(DISPLAY_WIDTH)))

    # --- a video: its frames ---------------------------------------------------------------
    @property
    def video(self) -> VideoReader | None:
        """The video the editor was opened on (its frames, :class:`~omniwidget.io.video.VideoReader`), None for an image."""
        return self._video

    @property
    def frame_count(self) -> int:
        """Frames of the video, 0 for an image."""
        return len(self._video) if self._video is not None else 0

    @property
    def frame_interval(self) -> float:
        """Seconds between the video's frames, 0.0 for an image."""
        return self._video.frame_interval if self._video is not None else 0.0

    @property
    def frame_time(self) -> float:
        """Seconds from the video's start to the frame shown, 0.0 for an image."""
        return self.frame * self.frame_interval

    def set_frame(self, frame: int | None = None, *, time: float | None = None) -> None:
        """Show another frame of the video (by index, or by ``time`` in seconds) and recompute the preview on it.

        The handles stay (no edit: no undo step, no autosave). The frame is read here; the
        preview is computed in the worker, as after an edit.

        Raises
        ------
        TypeError
            For an image, or neither or both of ``frame`` and ``time``.
        IndexError, ValueError
            For a frame or a time outside the video.
        """
        if self._video is None:
            raise TypeError("the editor shows an image, not a video: it has no frames to choose from")
        if frame is None and time is None:
            raise TypeError("give frame (an index) or time (seconds)")
        index = _frame_index(self._video, frame, time)
        if index == self.frame:
            return
        image = check_panorama(self._video.read(index))
        image.flags.writeable = False
        with self._lock:
            self._working = self._full_image = image
            self._scaled = {}
            self._preview_source = self._downscaled(2 * self._preview_width)
            self._full_result = None
            self._suggested, self._dropped = [], set()  # found on the frame shown before
        self._publish(frame=index, source=self.display_source())
        self._show_suggestions([])
        self._changed(self.document)

    @property
    def generation(self) -> int:
        """The number of the newest edit (or computation asked for); ``status["generation"]`` is the one shown."""
        return self._generation

    # --- the handles ---------------------------------------------------------------------
    @property
    def document(self) -> Handles:
        """The handles as a validated :class:`~omniwidget.Handles` document."""
        return Handles.from_dict(self.handles)

    def edit(self, handles: Handles | dict | str, record: bool = True) -> None:
        """Make ``handles`` the document: an edit (undoable when ``record``), recomputed and autosaved.

        Raises
        ------
        HandlesError
            If the document is invalid; nothing changes then.
        """
        doc = as_document(handles)
        new = doc.to_dict()
        if new == self.handles:
            return
        if record:
            self._undo.append(self.handles)
            del self._undo[:-HISTORY]
            self._redo.clear()
        self._publish(handles=new)
        self._clear_finished()
        if self._suggested:
            self._show_suggestions(self._shown_suggestions(doc))
        self._changed(doc)  # the preview starts first; the autosave is written meanwhile
        self._autosave(doc)

    # --- autosave ----------------------------------------------------------------------------
    def _open_autosave(self, home: Path, doc: Handles, given: bool) -> Handles:
        """Read this panorama's autosaves at ``home`` and beside it; return the document to start from.

        Without given handles the newest autosave with handles is restored, and the file it
        came from is the one this editor goes on writing (while it is its own); the others are
        offered in the notice and :attr:`other_autosaves`. A FIFO or device is never opened.
        """
        found = []  # (path, document or None, problem, whether it is no regular file)
        for path in _autosave_files(home):
            refused = _not_regular(path)
            saved, problem = (None, refused) if refused else _read_autosave(path)
            found.append((path, saved, problem, bool(refused)))
        kept = sorted(((p, d) for p, d, _, _ in found if d is not None and len(d)), key=lambda f: _mtime(f[0]), reverse=True)
        target, notes = home, []
        if kept and not given:
            target, saved = kept[0]
            self._undo.append(doc.to_dict())  # undo: start without them
            doc = saved
            self._restored = doc.to_dict()
            notes.append(f"restored {_count(saved)} from {target} (undo to start without them)")
        where = _in_use(target)
        for path, saved, problem, special in found:
            if path == home and saved is not None and len(saved) and given and saved != doc:
                fate = "it is kept" if where == "another kernel or program" else "the first edit replaces it"
                notes.append(f"the autosave {home} ({_count(saved)}) is not used: handles were given; {fate}")
            elif path == target and problem and not special:
                self._autosave_bad = True
                aside = f"the file is kept, as {_aside(path).name} from the first edit"
                notes.append(
                    f"the autosave is unreadable: {problem}; handles were given ({aside})"
                    if given
                    else f"could not restore the autosave: {problem}; opened with no handles ({aside})"
                )
            elif problem:
                own = ", and this editor autosaves to a file of its own" if path == target else ""
                notes.append(f"{problem}: it is left as it is{own}")
        self.other_autosaves = [p for p, _ in kept if p != target and not (given and p == home)]
        if self.other_autosaves:
            names = []
            for p, d in kept:
                if p in self.other_autosaves:
                    holder = _in_use(p)
                    names.append(f"{p.name} ({_count(d)}{f', open in {holder}' if holder else ''})")
            notes.append(f"other autosaves of this panorama are kept: {', '.join(names)}; load() takes one")
        if where == "this kernel":
            notes.append(
                f"another editor of this panorama is open in this kernel: this one takes {target.name} over at its first edit, "
                "the other keeps its handles apart"
            )
        elif where:
            notes.append(
                f"another editor (in {where}) has {target} open: this editor autosaves to a file of its own, so that neither erases the other's"
            )
        self._home, self.autosave_path, self._seen = home, target, _signature(target)
        self._notice = "; ".join(notes)
        return doc

    def _autosave(self, doc: Handles) -> None:
        """Write the autosave (whole or not at all) while it is this editor's, else a file of its own; a failure is shown, never raised."""
        if self.autosave_path is None:
            return
        try:
            with _HOLDERS_LOCK:
                notice = self._write_autosave((doc.to_json() + "\n").encode())
        except Exception as exc:  # noqa: BLE001 - the edit stands; the person is told it is not on disk
            notice = self._autosave_failed(exc)
        self._show_notice(notice)

    def _autosave_failed(self, exc: BaseException) -> str:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else _exception_text(exc)
        return f"could not autosave to {self.autosave_path} ({reason}): these handles are not on disk; Save or Download them"

    def _show_notice(self, notice: str) -> None:
        if notice != self._notice:
            self._notice = notice
            with self._lock:
                self._set_status(notice=notice)

    def _write_autosave(self, data: bytes) -> str:
        """Write ``data`` to the autosave if it is still this editor's, else to a new file of its own; return the notice."""
        path = self.autosave_path
        assert path is not None
        why = self._divert or self._not_mine(path)
        if why:
            return self._write_own(data, why)
        notice = self._own
        if self._autosave_bad:
            bad = _aside(path)
            if os.path.lexists(path):
                os.replace(path, bad)
            self._autosave_bad = False
            notice = f"the unreadable autosave was kept as {bad}"
        atomic_write_bytes(path, data)
        self._seen = _signature(path)
        self._hold(path, _lock(path))
        return notice

    def _not_mine(self, path: Path) -> str:
        """Why this editor must not write over ``path`` (another editor's file, or not a regular one), or "".

        An older editor of this kernel holding it hands it over (:meth:`_hand_over`).
        """
        refused = _not_regular(path)
        if refused:
            return f"{refused}; it is left as it is"
        holder = _HOLDERS.get(_path_key(path))
        if holder is not None and holder is not self:
            holder._hand_over(self)
            return ""
        if holder is None and _held_elsewhere(path):
            return f"another editor (in another kernel or program) has {path} open"
        if _signature(path) != self._seen:
            return f"{path} was written by another editor since this one {'wrote' if holder is self else 'opened'} it"
        return ""

    def _write_own(self, data: bytes, why: str) -> str:
        """Write ``data`` to a new file beside the autosave, this editor's own from now on; return the notice saying why."""
        assert self._home is not None
        path, claim = _create_numbered(self._home, data)
        self._release()
        self.autosave_path, self._seen, self._divert, self._autosave_bad = path, _signature(path), "", False
        self._hold(path, claim)
        self._own = f"{why}; this editor's handles are autosaved to {path} instead (no editor writes over another's)"
        return self._own

    def _hold(self, path: Path, claim: _Claim | None) -> None:
        """Make ``path`` (locked by ``claim``, if it could be) this editor's autosave."""
        old, self._claim = self._claim, claim
        if old is not None:
            old.close()
        _HOLDERS[_path_key(path)] = self

    def _release(self) -> None:
        """Let go of the autosave file (the file stays): another editor may take it."""
        with _HOLDERS_LOCK:
            path = self.autosave_path
            if path is not None and _HOLDERS.get(_path_key(path)) is self:
                del _HOLDERS[_path_key(path)]
            if self._claim is not None:
                self._claim.close()
                self._claim = None

    def _hand_over(self, newer: EditingSession) -> None:
        """Give the autosave to a newer editor of this panorama in this kernel (a cell run again); keep these handles apart.

        Handles the newer editor did not start from are written at once to a file of this
        editor's own; otherwise its next edit goes to one.
        """
        why = f"a newer editor of this panorama in this kernel took over {self.autosave_path}"
        self._release()
        try:
            if len(self.document) and self.handles != newer._restored:
                notice = self._write_own((self.document.to_json() + "\n").encode(), why)
            else:
                self._divert = why
                notice = f"{why}; this editor's next edit is autosaved to a file of its own"
        except Exception as exc:  # noqa: BLE001 - the newer editor goes on; this one says its handles are not on disk
            notice = self._autosave_failed(exc)
        self._show_notice(notice)

    def close(self) -> None:
        """Let go of the autosave file (it stays, for the next editor to restore); the handles stay in memory."""
        self._release()

    def _changed(self, doc: Handles) -> None:
        """After every change of the handles: recompute the preview (and the control points' outputs)."""
        self._publish(history={"undo": len(self._undo), "redo": len(self._redo)})
        key = self._key(doc.to_dict())
        self._schedule(lambda generation: self._compute(doc, key, generation, full=False))

    def _schedule(self, job: Callable[[int], None]) -> None:
        with self._lock:
            self._generation += 1
            generation = self._generation
            self._set_status(state="busy", message="computing...", error="", notice=self._notice, newest=generation)
        self._worker.submit(lambda: job(generation))

    def _report_error(self, message: str) -> None:
        """Show a refused command or edit; it stays until the next edit (a result still on its way keeps it)."""
        with self._lock:
            self._set_status(error=message)

    # --- computing -----------------------------------------------------------------------
    def _key(self, handles: dict | None = None) -> str:
        """The cache key of a result: the handles and, for a video, the frame they are warped on."""
        key = json.dumps(self.handles if handles is None else handles, sort_keys=True)
        return key if self._video is None else f"{key}#frame={self.frame}"

    def _full(self, doc: Handles, key: str, warn: bool) -> Any:
        """The full-size result of ``doc`` (whose :meth:`_key` is ``key``), kept for the next ask."""
        from ..raster.pipeline import warp

        cached = self._full_result
        if cached is not None and cached[0] == key:
            return cached[1]
        result = warp(self.image, doc, warn=warn, previous=self._preview_result)  # the preview's weights, when they are these
        self._full_result = (key, result)
        return result

    def _warp(self, doc: Handles, key: str, full: bool) -> Any:
        from ..raster.pipeline import warp

        if full or self._preview_width == self._width:
            return self._full(doc, key, warn=False)
        # the last preview's weights start the solver: a drag changes them little
        return warp(self._preview_source, doc, width=self._preview_width, warn=False, previous=self._preview_result)

    def _compute(self, doc: Handles, key: str, generation: int, full: bool) -> Any:
        """Compute and show the result of ``doc``; return it (None when it failed, which is shown)."""
        start = time.perf_counter()
        try:
            result = self._warp(doc, key, full)
            outputs = _output_points(doc, result.constraints)
            if not _finite_outputs(outputs):
                raise FloatingPointError("the handles' outputs are not finite numbers")
            if result.image.dtype.kind == "f" and not np.isfinite(result.image).all():  # the input is finite (check_panorama)
                raise FloatingPointError("the result has pixels that are not finite numbers")
            image = _jpeg(_display_rgb8(result.image, DISPLAY_WIDTH))
            folds = _fold_overlay(result.folds.mask)
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles and the last good image stay
            with self._lock:
                if generation == self._generation:
                    self.last_error = exc
                    message = f"could not compute the result ({_exception_text(exc)}); the handles are kept and the last good result stays"
                    self._set_status(state="error", message=message, error=message)
            return None
        seconds = time.perf_counter() - start
        kept = _kept_lines(result)
        pole = tuple(f"handles[{i}] (line) passes " for i in kept)  # their warnings say why; they are no conflict
        conflicts = sorted({int(i) for w in result.warnings if not w.startswith(pole) for i in _HANDLE_NAME.findall(w)})
        with self._lock:
            if generation != self._generation:
                return result  # a newer edit is on its way: this result is stale
            self._preview_result = result
            self._publish(
                preview=image,
                folds=folds,
                outputs=outputs,
                status={
                    **self.status,
                    "state": "idle",
                    "error": self.status.get("error", ""),
                    "message": f"{result.image.shape[1]} x {result.image.shape[0]} in {seconds:.2f} s",
                    "result": f"{result.image.shape[1]} x {result.image.shape[0]} in {seconds:.2f} s",
                    "warnings": list(result.warnings),
                    "warning_kinds": _warning_kinds(result),
                    "conflicts": conflicts,
                    "kept": kept,
                    "reaches": _reaches(result.handles),
                    "fold_area": float(result.folds.area),
                    "seconds": seconds,
                    "width": int(result.image.shape[1]),
                    "generation": generation,
                    "quality": "",
                },
            )
        if self._measure and result.weights is not None:
            self._quality.submit(lambda: self._measure_quality(result, generation))
        return result

    def _measure_quality(self, result: Any, generation: int) -> None:
        """The quality figures of a result on screen, in a line of the status (measured after it is shown)."""
        time.sleep(QUALITY_DELAY)  # a drag goes on: let the next edit's computation have the cores
        if generation != self._generation:
            return
        try:
            line = result.quality.line()
        except Exception as exc:  # noqa: BLE001 - a figure that cannot be measured is said, not raised
            line = f"could not measure the quality ({_exception_text(exc)})"
        with self._lock:
            if generation == self._generation:
                self._set_status(quality=line)

    def wait(self, timeout: float | None = 120.0) -> dict:
        """Block until the newest edit's result is shown (or failed); return :attr:`status`.

        Raises
        ------
        TimeoutError
            If the computation takes longer than ``timeout`` seconds.
        """
        if not self._worker.wait(timeout):
            raise TimeoutError(f"the editor's computation did not finish within {timeout} s")
        return dict(self.status)

    def idle(self, timeout: float | None = 120.0) -> bool:
        """Block until the preview, the quality figures, the live drag's basis, Suggest lines and Level are all done; False on timeout."""
        workers = (self._worker, self._quality, self._live, self._suggest_worker, self._level_worker, self._straighten_worker)
        return all(worker.wait(timeout) for worker in workers)

    @property
    def result(self) -> Result:
        """The full-resolution :class:`~omniwidget.Result` of the current handles (computed on demand)."""
        return self._full(self.document, self._key(), warn=True)

    @property
    def preview_result(self) -> Result | None:
        """The :class:`~omniwidget.Result` last shown, or None."""
        return self._preview_result

    def compute_full(self) -> None:
        """Compute the full-resolution result in the background and show it."""
        doc, key = self.document, self._key()
        self._schedule(lambda generation: self._compute(doc, key, generation, full=True))

    # --- save image ---------------------------------------------------------------------------
    def save_image(self, path: str | os.PathLike[str] | None = None, *, gpano: bool = True) -> Path:
        """Write the full-size result of the current handles (whole or not at all); return where.

        Parameters
        ----------
        path : path-like, optional
            Where to write (its suffix picks the format). Default: next to the panorama when
            the editor was opened from a file, ``room.jpg`` giving ``room-rectified.jpg`` in
            the input's format, or PNG (then TIFF, then ``.npy``) where that format cannot
            hold the result (alpha in a JPEG, say); in the working folder as
            ``panorama-rectified.png`` when it was opened from an array (and as
            ``<stem>-rectified.<suffix>`` for the bundled sample, never written next to).
        gpano : bool
            Write the Photo Sphere XMP when the panorama has none (the result is a whole
            sphere). The panorama file's metadata is carried either way, brought up to date
            (:func:`omniwidget.io.metadata.output_metadata`): EXIF (orientation 1, the
            sizes), ICC profile, XMP with its GPano sizes and pose (levelled: pitch and roll 0).

        Raises
        ------
        ImageError
            If the file cannot be written (a folder that is not there or not writable) or
            ``path`` is the input panorama, which is never overwritten. The error is also
            shown in the widget (:attr:`status` ``error``); the handles are kept.

        The editor's Save image button does the same in the editor's worker (the widget never waits)
        and also offers the file as a browser download. A panorama wider than
        :data:`~omniwidget.raster.strips.STREAM_WIDTH` is made and written in strips
        (:meth:`_save_in_strips`: read from disk a patch at a time when large, its progress in
        :attr:`status` ``["saving"]``) and not offered as a download.
        """
        if self._in_strips():
            try:
                return self._save_in_strips(self.document, path, gpano=gpano)
            except Exception as exc:
                self._report_error(self._save_image_error(exc))
                raise
        try:
            result = self._full(self.document, self._key(), warn=False)
            written = self._write_result(result.image, path, self.document, gpano=gpano)
        except Exception as exc:
            self._report_error(self._save_image_error(exc))
            raise
        self._say_saved(written, result.image.shape)
        return written

    def _in_strips(self) -> bool:
        """Whether Save image makes the result in strips: a panorama file wider than the command line's STREAM_WIDTH."""
        from ..raster.strips import STREAM_WIDTH

        return self._image_path is not None and self._video is None and self._width > STREAM_WIDTH

    def _save_in_strips(self, doc: Handles, path: str | os.PathLike[str] | None, *, gpano: bool = True) -> Path:
        """Save image for a panorama too large to warp whole: made and written in strips, its progress in :attr:`status`.

        :func:`~omniwidget.app.strips.strips_of_file` chooses where the pixels come from (a patch at a time from disk
        for a panorama above :data:`~omniwidget.io.large.STREAM_BYTES` decoded, else the panorama in memory) and runs
        the method on its map grid. ``status["saving"]`` says the rows written and their total as they go, and the
        message the share.
        """
        from ..io.images import write_image_strips
        from .strips import strips_of_file

        if self._image_path is None:  # pragma: no cover - _in_strips says so
            raise ImageError("only a panorama opened from a file is saved in strips")
        target = self._target(path, np.empty((0, self._width, *self._working.shape[2:]), self._working.dtype))
        height = self._width // 2
        said = f"saving {target.name} ({self._width} x {height}): reading the panorama..."
        self._set_status(message=said, saving={"done": 0, "total": height}, save={"state": "running", "message": said})

        def progress(rows: int) -> None:
            said = f"saving {target.name}: {100 * rows // height}% of {height} rows"
            self._set_status(message=said, saving={"done": rows, "total": height}, save={"state": "running", "message": said})

        with strips_of_file(self._image_path, doc, image=self._full_image, output=target) as made:
            meta = self._output_metadata(doc, made.shape, gpano)
            write_image_strips(target, made.shape, made.dtype, made.image_strips(), progress=progress, meta=meta)
        self._say_saved(target, made.shape)
        return target

    def _write_result(self, image: NDArray, path: str | os.PathLike[str] | None, doc: Handles | None = None, *, gpano: bool = True) -> Path:
        target = self._target(path, image)
        write_image(target, image, self._output_metadata(doc, image.shape, gpano))
        return target

    def _output_metadata(self, doc: Handles | None, shape: tuple[int, ...], gpano: bool) -> Metadata:
        """What Save image writes with the result: the panorama file's metadata brought up to date, GPano as ``gpano`` says."""
        source = read_metadata(self._image_path) if self._image_path is not None and self._video is None else None
        levelled = doc is not None and doc.options.up is not None
        return output_metadata(source, shape[1], shape[0], gpano=gpano, levelled=levelled)

    def _target(self, path: str | os.PathLike[str] | None, image: NDArray) -> Path:
        """Where Save image writes ``image`` (:func:`_result_location`), refused if it is the input panorama."""
        target = Path(path) if path is not None else _result_location(self._image_path, image)
        if self._image_path is not None and _same_file(target, self._image_path):
            raise ImageError(f"{target}: is the input panorama, which the editor never overwrites; name another file")
        return target

    @staticmethod
    def _save_image_error(exc: BaseException) -> str:
        text = str(exc) if isinstance(exc, ImageError) else _exception_text(exc)
        return f"could not save the image: {text}; the handles are kept"

    def _say_saved(self, path: Path, shape: tuple[int, ...]) -> None:
        with self._lock:
            message = f"{shape[1]} x {shape[0]} saved to {path}"
            self._set_status(message=message, saved=str(path), saving=None, save={"state": "done", "message": message})

    def _save_image_job(self, doc: Handles, key: str, generation: int) -> None:
        """In the worker: compute and show the full-size result, write it and send it for download.

        A panorama made in strips (:meth:`_in_strips`) is written without being shown or sent: a file of
        gigabytes is no browser download; the status names where it is.
        """
        if self._in_strips():
            try:
                self._save_in_strips(doc, None)
            except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
                self.last_error = exc
                self._report_error(self._save_image_error(exc))
                self._set_save("error", self._save_image_error(exc))
            return
        result = self._compute(doc, key, generation, full=True)
        if result is None:
            self._set_save("error", "could not save the image: the result could not be computed")
            return  # the computation's error is shown
        try:
            path = self._write_result(result.image, None, doc)
            data = path.read_bytes()
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self.last_error = exc
            self._report_error(self._save_image_error(exc))
            self._set_save("error", self._save_image_error(exc))
            return
        self._say_saved(path, result.image.shape)
        mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
        self._on_message({"op": "image_file", "name": path.name, "mime": mime}, [data])

    def _save_image_in_worker(self) -> None:
        doc, key = self.document, self._key()
        self._set_save("running", "saving the image: computing the full-size result...")
        self._schedule(lambda generation: self._save_image_job(doc, key, generation))

    # --- save video ---------------------------------------------------------------------------
    def save_video(self, path: str | os.PathLike[str] | None = None, *, wait: bool = False) -> Path:
        """Warp the whole video by the map of the current handles and write it, in a thread of its own; return where.

        The map is the full-size result's (:meth:`Result.inverse_map` at the video's width),
        computed on the frame shown; every frame is then resampled by it
        (:func:`~omniwidget.io.video.warp_video`: the sound, time stamps and spherical
        metadata kept). :attr:`status` ``["video"]`` follows the job: ``state`` ("map",
        "running", "done", "cancelled" or "error"), ``done`` and ``total`` frames, ``fps``,
        ``path`` and a ``message``; :meth:`cancel_video` stops it, and nothing is written
        then. The editor goes on meanwhile (edits, other frames).

        Parameters
        ----------
        path : path-like, optional
            ``.mp4``, ``.m4v`` or ``.mov``. Default: next to the video, ``clip.mp4`` giving
            ``clip-rectified.mp4`` (MP4 for other containers).
        wait : bool
            Block until the video is written (or failed, or was cancelled) and raise its
            error, for scripts.

        Raises
        ------
        TypeError
            If the editor shows an image.
        VideoError
            If a video is being saved already (``wait`` or not), or, with ``wait``, the
            video could not be written; VideoCancelled when cancelled meanwhile.
        """
        if self._video is None or self._image_path is None:
            raise TypeError("the editor shows an image, not a video: use save_image")
        with self._lock:
            if self._video_job is not None and self._video_job.is_alive():
                raise VideoError("a video is being saved already; wait for it or cancel it first")
            target = Path(path) if path is not None else _video_location(self._image_path)
            doc, key = self.document, self._key()
            cancel = threading.Event()
            self._video_cancel = cancel
            self._video_error = None
            self._video_report = None
            job = threading.Thread(target=self._video_job_run, args=(doc, key, target, cancel), name="omniwidget-save-video", daemon=True)
            self._video_job = job
        message = f"saving the video to {target}: computing the map..."
        self._set_video(state="map", done=0, total=self.frame_count, fps=0.0, path=str(target), message=message)
        _VIDEO_JOBS.add((job, cancel))
        job.start()
        if wait:
            job.join()
            if self._video_error is not None:
                raise self._video_error
        return target

    def cancel_video(self) -> bool:
        """Stop the video being saved (its partial file is removed); False when none is."""
        job, cancel = self._video_job, self._video_cancel
        if job is None or cancel is None or not job.is_alive():
            return False
        cancel.set()
        return True

    def wait_video(self, timeout: float | None = None) -> VideoReport | None:
        """Block until the video being saved is written, failed or cancelled; its report (None unless written)."""
        job = self._video_job
        if job is not None:
            job.join(timeout)
            if job.is_alive():
                raise TimeoutError(f"the video was not saved within {timeout} s")
        return self._video_report

    def _set_video(self, **fields: Any) -> None:
        with self._lock:
            self._set_status(video={**self.status.get("video", {}), **fields})

    def _video_job_run(self, doc: Handles, key: str, target: Path, cancel: threading.Event) -> None:
        """The save video thread: the map, then every frame; its progress and end in ``status["video"]``."""
        try:
            self._save_video(doc, key, target, cancel)
        finally:
            _VIDEO_JOBS.discard((threading.current_thread(), cancel))

    def _save_video(self, doc: Handles, key: str, target: Path, cancel: threading.Event) -> None:
        from .video import VideoCancelled, warp_video

        assert self._image_path is not None
        start = time.perf_counter()
        shown = 0.0

        def progress(done: int, total: int | None) -> bool:
            nonlocal shown
            now = time.perf_counter()
            if now - shown >= 0.2 or done == total:  # a few updates a second reach the browser
                shown = now
                fps = done / max(now - start, 1e-9)
                message = f"saving the video: frame {done} of {total or '?'}, {fps:.1f} fps"
                self._set_video(state="running", done=done, total=total or done, fps=round(fps, 1), message=message)
            return not cancel.is_set()

        try:
            if self._image_path is not None and _same_file(target, self._image_path):
                raise ImageError(f"{target}: is the input video, which the editor never overwrites; name another file")
            the_map = self._full(doc, key, warn=False).inverse_map()
            if cancel.is_set():
                raise VideoCancelled(f"cancelled before the first frame; {target} was not written")
            start = time.perf_counter()
            report = warp_video(self._image_path, target, inverse_map=the_map, progress=progress, cancel=cancel)
        except VideoCancelled as exc:
            self._video_error = exc
            self._set_video(state="cancelled", message=f"saving the video was cancelled: {exc}")
            return
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self._video_error = exc
            self.last_error = exc
            reason = str(exc) if isinstance(exc, ImageError) else _exception_text(exc)  # a VideoError is an ImageError
            self._set_video(state="error", message=f"could not save the video: {reason}")
            return
        self._video_report = report
        self._set_video(
            state="done",
            done=report.frames,
            total=report.frames,
            fps=round(report.fps, 1),
            message=(
                f"{report.frames} frames ({report.size[0]} x {report.size[1]}) saved to {target} "
                f"in {report.seconds:.1f} s, {report.fps:.1f} fps"
            ),
        )

    # --- suggested lines and levelling (omniwidget.detect) ---------------------------------
    def _detect_source(self) -> NDArray:
        """The panorama the detector looks at (:data:`~omniwidget.detect.DETECT_WIDTH` wide at most, as it would reduce it): kept, made once."""
        from ..detect import DETECT_WIDTH

        with self._lock:
            return self._downscaled(DETECT_WIDTH)

    def _set_detect(self, job: str, **fields: Any) -> None:
        """``status[job]`` (``"suggest"``, ``"level"`` or ``"straighten"``): its ``state`` ("running", "done" or "error") and ``message``."""
        with self._lock:
            self._set_status(**{job: fields})

    def _shown_suggestions(self, doc: Handles | None = None) -> list[dict]:
        """The suggestions not dropped and not in the document (as line handles), JSON-ready; ``key`` names one."""
        doc = self.document if doc is None else doc
        lines = {_line_key(h.start, h.end) for h in doc.handles if isinstance(h, LineHandle)}
        shown = []
        for key, s in enumerate(self._suggested):
            if key in self._dropped or _line_key(s.start, s.end) in lines:
                continue
            shown.append(
                {
                    "key": key,
                    "start": [float(v) for v in s.start],
                    "end": [float(v) for v in s.end],
                    "length": round(float(s.length), 3),
                    "confidence": round(float(s.confidence), 3),
                }
            )
        return shown

    def _wait_detect(self, job: str, worker: Latest, wait: bool) -> None:
        if wait:
            worker.wait(None)
            error = self._detect_errors[job]
            if error is not None:
                raise error

    def suggest_lines(self, *, max_lines: int = 40, wait: bool = False) -> None:
        """Find straight edges in the panorama (:func:`omniwidget.detect.suggest_lines`) in the background and show them.

        The suggestions (:attr:`suggestions`, drawn dashed on the input) replace any shown
        before; none is a handle until accepted (:meth:`accept_suggestion`,
        :meth:`accept_all_suggestions`). :attr:`status` ``["suggest"]`` follows the job:
        ``state`` ("running", "done" or "error") and ``message``.

        Parameters
        ----------
        max_lines : int
            At most this many suggestions, best first.
        wait : bool
            Block until they are found, and raise the detector's error, for scripts.
        """
        max_lines = whole_number(max_lines, "max_lines", minimum=1)
        self._detect_errors["suggest"] = None
        self._set_detect("suggest", state="running", message="finding straight edges...")
        self._suggest_worker.submit(lambda: self._suggest_job(max_lines))
        self._wait_detect("suggest", self._suggest_worker, wait)

    def _suggest_job(self, max_lines: int) -> None:
        from ..detect import suggest_lines

        start = time.perf_counter()
        try:
            found = suggest_lines(self._detect_source(), max_lines=max_lines)
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self._detect_errors["suggest"] = self.last_error = exc
            reason = str(exc) if isinstance(exc, OmniwidgetError) else _exception_text(exc)
            self._set_detect("suggest", state="error", message=f"could not suggest lines: {reason}")
            return
        seconds = time.perf_counter() - start
        self._suggested, self._dropped = list(found), set()
        shown = self._shown_suggestions()
        self._publish(suggestions=shown)
        what = "click one to accept it, Accept all, or Drop them" if shown else "none found"  # the prompt: _show_suggestions
        self._set_detect("suggest", state="done", count=len(shown), message=f"{len(shown)} suggested lines in {seconds:.2f} s: {what}")

    def _suggestion(self, key: Any) -> Suggestion:
        shown = {s["key"] for s in self.suggestions}
        if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or int(key) not in shown:
            raise IndexError(f"suggestion {key!r} is not shown (accepted or dropped already, or suggested before the last Suggest lines)")
        return self._suggested[int(key)]

    def accept_suggestion(self, key: int) -> None:
        """Add the suggestion ``key`` (its ``key`` in :attr:`suggestions`) as a line handle: one undoable edit."""
        line = self._suggestion(key).handle()
        self._edit(lambda items: items.append(line))

    def accept_all_suggestions(self) -> int:
        """Add every suggestion shown as line handles, in one undoable edit; return how many."""
        lines = [self._suggested[s["key"]].handle() for s in self.suggestions]
        if lines:
            self._edit(lambda items: items.extend(lines))
        return len(lines)

    def drop_suggestions(self, key: int | None = None) -> None:
        """Stop showing the suggestion ``key``, or all of them (no edit: they were no handles)."""
        if key is None:
            self._dropped = set(range(len(self._suggested)))
        else:
            self._suggestion(key)
            self._dropped.add(int(key))
        self._show_suggestions(self._shown_suggestions())

    def _show_suggestions(self, shown: list[dict]) -> None:
        """Publish the suggestions shown and make Suggest lines' prompt say how many are left, or go when none is.

        The prompt ("click one to accept it, Accept all, or Drop them") is for suggestions
        on screen only: once every one was accepted or dropped it is cleared, so that no
        message asks for a click on buttons that are greyed.
        """
        before = len(self.suggestions)
        self._publish(suggestions=shown)
        job = self.status.get("suggest") or {}
        if job.get("state") != "done" or len(shown) == before:
            return
        if shown:
            message = f"{len(shown)} suggested line{'s' * (len(shown) > 1)} left: click one to accept it, Accept all, or Drop them"
        else:
            message = ""
        self._set_detect("suggest", **{**job, "count": len(shown), "message": message})

    def level(self, *, wait: bool = False, answer: bool = False) -> None:
        """Level the panorama: find the camera's tilt (:func:`omniwidget.detect.level`) in the background and undo it.

        The rotation is applied as one undoable edit (:func:`omniwidget.detect.level_document`:
        ``options.up`` set, the mode kept, the handles' outputs carried by the turn), on the
        handles as they are when it is found. Too few vertical edges: the status says so
        (``status["error"]`` and ``status["level"]``) and nothing changes.

        Parameters
        ----------
        wait : bool
            Block until it is applied, and raise its error (a :class:`~omniwidget.errors.LevelError`), for scripts.
        answer : bool
            Tell the front end ``{"done": "level"}`` once the handles changed (or did not).

        Raises
        ------
        OmniwidgetError
            If the panorama is being levelled already.
        """
        with self._lock:
            if self._levelling:
                raise OmniwidgetError("the panorama is being levelled already; one moment")
            self._levelling = True
        self._detect_errors["level"] = None
        self._set_detect("level", state="running", message="levelling: finding the vertical edges...")
        self._level_worker.submit(lambda: self._level_job(answer))
        self._wait_detect("level", self._level_worker, wait)

    def _level_job(self, answer: bool) -> None:
        from ..detect import level, level_document

        start = time.perf_counter()
        try:
            try:
                found = level(self._detect_source())
                seconds = time.perf_counter() - start
                for _ in range(3):  # on the handles as they are: an edit made while level_document ran is never undone
                    base = self.handles
                    levelled = level_document(Handles.from_dict(base), found)
                    if self.handles == base:
                        self.edit(levelled)
                        break
                else:
                    raise OmniwidgetError("the handles kept changing while the rotation was applied to them; click Level again")
            except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
                self._detect_errors["level"] = self.last_error = exc
                reason = str(exc) if isinstance(exc, OmniwidgetError) else _exception_text(exc)
                message = f"could not level the panorama: {reason}; the handles are unchanged"
                self._set_detect("level", state="error", message=message)
                self._report_error(message)
                return
            message = (
                f"levelled: pitch {found.pitch:+.2f}°, roll {found.roll:+.2f}° from {len(found.edges)} vertical edges "
                f"found in {seconds:.2f} s (undo to take it back)"
            )
            pitch, roll = round(float(found.pitch), 4), round(float(found.roll), 4)
            self._set_detect("level", state="done", message=message, pitch=pitch, roll=roll, edges=len(found.edges))
        finally:
            self._levelling = False
            if answer:
                self._on_message({"done": "level"}, [])

    def straighten(self, *, wait: bool = False, answer: bool = False) -> None:
        """Straighten the panorama in one step (:func:`omniwidget.straighten`) in the background: level, find the structure, rectify it.

        The handles it used replace the document as one undoable edit (the lines, the
        default mode and ``options.up``); the suggestions shown go. :attr:`status`
        ``["straighten"]`` follows the job (``state`` and ``message``: what was levelled, how
        many lines were straightened and why others were left out). The structure is found
        on the panorama as the detector sees it (:data:`~omniwidget.detect.DETECT_WIDTH` wide
        at most), and checked there by a warp.

        Parameters
        ----------
        wait : bool
            Block until the handles are loaded, and raise the job's error, for scripts.
        answer : bool
            Tell the front end ``{"done": "straighten"}`` once the handles changed (or did not).

        Raises
        ------
        OmniwidgetError
            If the panorama is being straightened already.
        """
        with self._lock:
            if self._straightening:
                raise OmniwidgetError("the panorama is being straightened already; one moment")
            self._straightening = True
        self._detect_errors["straighten"] = None
        self._set_detect("straighten", state="running", message="straightening: levelling, finding the structure, rectifying it...")
        self._straighten_worker.submit(lambda: self._straighten_job(answer))
        self._wait_detect("straighten", self._straighten_worker, wait)

    def _straighten_job(self, answer: bool) -> None:
        from .straighten import straighten

        start = time.perf_counter()
        try:
            try:
                done = straighten(self._detect_source())
                self.drop_suggestions()  # the structure replaces them
                self.edit(done.handles)
            except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
                self._detect_errors["straighten"] = self.last_error = exc
                reason = str(exc) if isinstance(exc, OmniwidgetError) else _exception_text(exc)
                message = f"could not straighten the panorama: {reason}; the handles are unchanged"
                self._set_detect("straighten", state="error", message=message)
                self._report_error(message)
                return
            seconds = time.perf_counter() - start
            message = f"straightened in {seconds:.1f} s: {done.structure.summary()} (undo to take it back)"
            self._set_detect("straighten", state="done", message=message, lines=len(done.structure.used), dropped=len(done.structure.dropped))
        finally:
            self._straightening = False
            if answer:
                self._on_message({"done": "straighten"}, [])

    # --- edits -----------------------------------------------------------------------------
    def undo(self) -> bool:
        """Go back one edit; False when there is none."""
        return self._step(self._undo, self._redo)

    def redo(self) -> bool:
        """Redo the edit last undone; False when there is none."""
        return self._step(self._redo, self._undo)

    def _step(self, source: list[dict], target: list[dict]) -> bool:
        if not source:
            return False
        target.append(self.handles)
        self.edit(source.pop(), record=False)
        return True

    def _edit(self, change: Callable[[list], None]) -> None:
        doc = self.document
        items = list(doc.handles)
        change(items)
        self.edit(replace(doc, handles=tuple(items)))

    def _handle(self, index: int) -> Any:
        items = self.document.handles
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(items):
            raise IndexError(f"handles[{index}]: there are {len(items)} handles")
        return items[index]

    def rectify_all(self) -> None:
        """Rectify every line together (Sec. 3.4): the paper's "rectify all lines"."""
        doc = self.document
        items = tuple(replace(h, rectify=True, targets=None) if isinstance(h, LineHandle) else h for h in doc.handles)
        self.edit(Handles(items, Options(rectify="all")))

    def rectify_line(self, index: int) -> None:
        """Rectify line ``index`` and hold every other handle where it is ("rectify current line")."""
        from ..method.edits import rectify_line

        self._handle(index)
        self.edit(rectify_line(self.document, index))

    def reset(self, index: int) -> None:
        """Undo every transformation of handle ``index``: its output goes back to where it was drawn."""
        h = self._handle(index)
        self._edit(lambda items: items.__setitem__(index, _reset(h)))

    def move_arrow(self, index: int, tip: Any, which: Literal["east", "west"] = "east") -> None:
        """Drag point handle ``index``'s output arrow tip to ``tip`` ``[lon, lat]``: it turns and zooms."""
        h = self._handle(index)
        if not isinstance(h, PointHandle):
            raise HandlesError(f"handles[{index}]", f"a {h.kind} handle has no arrows")
        if which not in ("east", "west"):
            raise ValueError(f"which must be 'east' or 'west', got {which!r}")
        moved = h.with_arrow_tip(tip, which)
        self._edit(lambda items: items.__setitem__(index, moved))

    # --- files -------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write the handles file (whole or not at all); return where.

        Parameters
        ----------
        path : path-like, optional
            Default :attr:`handles_path`: ``day1/room.handles.json`` next to ``day1/room.jpg``
            when the editor was opened from a file in a folder it may write to; otherwise
            (an array, the bundled sample, a folder not to write to) ``<stem>.handles.json``
            in the working folder.

        Raises
        ------
        FileExistsError
            If ``path`` is not given, the default file is the working folder's (a name other
            panoramas may share) and it is there already, not saved or loaded by this editor:
            it may hold another panorama's handles, which Save never writes over. Pass a path,
            or set :attr:`handles_path`.
        """
        if path is None:
            path = self.handles_path
            if self._guard_handles and path == self._default_handles and os.path.lexists(path) and _signature(path) != self._handles_written:
                raise FileExistsError(
                    f"{path.absolute()}: not saved: that file was not written by this editor and may hold another panorama's "
                    f"handles (in the working folder it is named after the image's name only); save to another file "
                    f"(save(path), or set handles_path)"
                )
        path = Path(path)
        save_handles(self.document, path)
        self._note_handles_file(path)
        return path

    def load(self, path: str | os.PathLike[str]) -> None:
        """Replace the handles by those of a handles file (an undoable edit)."""
        self.edit(load_handles(path))
        self._note_handles_file(Path(path))

    def _note_handles_file(self, path: Path) -> None:
        """Remember the default handles file as this editor saved or read it: Save may write over it."""
        if _same_file(path, self._default_handles):
            self._handles_written = _signature(self._default_handles)

    # --- the front end's commands -----------------------------------------------------------
    def _solve_drag(self, document: Any) -> None:
        """Compute the preview of the handles a drag on the result has reached: no edit (no undo step, no autosave).

        The live frame then draws from this result's weights (:meth:`live_basis_message`); the
        document itself changes when the drag ends.
        """
        doc = as_document(document)
        key = self._key(doc.to_dict())
        self._schedule(lambda generation: self._compute(doc, key, generation, full=False))

    def live_basis_message(self, index: Any) -> None:
        """Send the browser what it needs to redraw the result live while handle ``index`` is dragged (:mod:`omniwidget.raster.live`).

        The basis of the result on screen: the other controls' part of eq. (2) and the
        handle's own weights per preview pixel, as half floats. Nothing is sent when no
        result is on screen or the handle has no control in it (a handle drawn meanwhile);
        the browser then shows the drag as before, the kernel's result on release.
        """
        from ..raster.live import live_basis

        with self._lock:
            result, generation = self._preview_result, self.status.get("generation")
        if result is None or not isinstance(index, int) or not 0 <= index < len(result.handles):
            return
        try:
            basis = live_basis(result, index)
        except ValueError:
            return
        height, width = basis.fixed.shape[:2]
        header = {
            "op": "live",
            "index": index,
            "generation": generation,
            "controls": len(basis.controls),
            "carry": result.handles.options.anchor is not None,
            "turn": None if (turn := result.handles.options.levelling()) is None else turn.as_dict(),
            "width": width,
            "height": height,
            "origin": list(basis.origin),
            "size": basis.size,
        }
        self._on_message(header, [basis.packed().view(np.uint16).tobytes()])

    def command(self, content: Any) -> None:
        """Apply a command of the front end (``{"op": ...}``); a refused one is shown in the status, the handles kept.

        Every command is answered ``{"done": op}`` once it has changed the handles, so that the
        front end starts no edit from the handles before it.
        """
        if not isinstance(content, dict):
            return
        op = content.get("op")
        index: Any = content.get("index")  # checked by the methods, as every value of the front end
        key: Any = content.get("key")
        answered = False
        try:
            if op == "undo":
                self.undo()
            elif op == "redo":
                self.redo()
            elif op == "rectify_all":
                self.rectify_all()
            elif op == "rectify_line":
                self.rectify_line(index)
            elif op == "reset":
                self.reset(index)
            elif op == "arrow":
                self.move_arrow(index, content.get("tip"), content.get("which", "east"))
            elif op == "drag":
                self._solve_drag(content.get("handles"))
            elif op == "refresh":
                self._changed(self.document)
            elif op == "live":
                self._live.submit(lambda: self.live_basis_message(content.get("index")))
            elif op == "full":
                self.compute_full()
            elif op == "save_image":
                self._save_image_in_worker()
            elif op == "save_video":
                self.save_video()
            elif op == "cancel_video":
                self.cancel_video()
            elif op == "frame":
                self.set_frame(content.get("frame"))
            elif op == "suggest":
                self.suggest_lines()
            elif op == "accept_suggestion":
                self.accept_suggestion(key)
            elif op == "accept_all":
                self.accept_all_suggestions()
            elif op == "drop_suggestions":
                self.drop_suggestions(key)
            elif op == "level":
                self.level(answer=True)
                answered = True  # {"done": "level"} once the rotation is applied
            elif op == "straighten":
                self.straighten(answer=True)
                answered = True  # {"done": "straighten"} once the handles are loaded
            elif op == "save":
                path = self.save()
                said = f"saved {len(self.document)} handles to {path}"
                self._set_status(message=said, save={"state": "done", "message": said})
            elif op == "load":
                name = str(content.get("name") or "the file")
                try:
                    doc = Handles.from_json(content.get("text", ""))
                except HandlesError as exc:
                    raise HandlesError(f"{name}: {exc.where}" if exc.where else name, exc.problem) from None
                self.edit(doc)
            else:
                raise ValueError(f"unknown command from the browser: {op!r}")
        except Exception as exc:  # noqa: BLE001 - a person's click: show it, keep the handles
            self._report_error(str(exc) if isinstance(exc, HandlesError) else f"{type(exc).__name__}: {exc}")
        finally:  # after the handles it changed: the browser starts no edit from the handles before it
            if not answered:
                self._on_message({"done": op}, [])
