"""The command line: ``omniwidget warp``, ``straighten``, ``level``, ``suggest``, ``view``, ``demo`` and ``schema``.

A successful run ends with one line on stderr saying what was written, its size, the time
and how the result came out (``--quiet``: nothing). Bad input of any kind gives one line on
stderr saying what and where, in the command line's words (the option that fixes it), exit
status 2, no traceback and no output file; so does an output that would overwrite an input,
the handles file, the map or another output (:func:`_refuse_overwrites`), before any work.
Outputs are written whole (a hidden temporary file beside each, synced, then a rename); Ctrl+C
and SIGTERM remove it on the way out (exit 130 and 143), and what a ``kill -9`` left is
removed by the next run on the same output.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from .._files import refuse_overwrites, remove_leftovers
from .._lazy import lazy
from .._version import __version__
from ..errors import ImageError, OmniwidgetError

# Every module a command uses, named here and loaded when a command first reads it: `omniwidget --help`
# and a refused argument load none of them.
if TYPE_CHECKING:
    import cv2
    import numpy as np

    from .. import data as omniwidget_data
    from .. import detect
    from ..detect import structure
    from ..document import handles as document_handles
    from ..document import schema
    from ..evaluate import quality
    from ..io import draw, frames, images
    from ..io import metadata as io_metadata
    from ..io import video as io_video
    from ..raster import perspective, pipeline, strips
    from ..raster.pipeline import Result
    from . import batch
    from . import frames as app_frames
    from . import straighten as app_straighten
    from . import strips as app_strips
    from . import video as app_video
else:
    io_metadata = lazy("omniwidget.io.metadata")
    pipeline = lazy("omniwidget.raster.pipeline")
    quality = lazy("omniwidget.evaluate.quality")
    cv2 = lazy("cv2")
    document_handles = lazy("omniwidget.document.handles")
    images = lazy("omniwidget.io.images")
    strips = lazy("omniwidget.raster.strips")
    np = lazy("numpy")
    app_strips = lazy("omniwidget.app.strips")
    frames = lazy("omniwidget.io.frames")
    app_frames = lazy("omniwidget.app.frames")
    batch = lazy("omniwidget.app.batch")
    io_video = lazy("omniwidget.io.video")
    app_video = lazy("omniwidget.app.video")
    detect = lazy("omniwidget.detect")
    app_straighten = lazy("omniwidget.app.straighten")
    structure = lazy("omniwidget.detect.structure")
    omniwidget_data = lazy("omniwidget.data")
    draw = lazy("omniwidget.io.draw")
    perspective = lazy("omniwidget.raster.perspective")
    schema = lazy("omniwidget.document.schema")

EXIT_BAD_INPUT = 2
#: Ctrl+C, as a shell reports a process ended by SIGINT (128 + 2).
EXIT_INTERRUPTED = 130
#: SIGTERM (``kill``, a job scheduler, a container stopped), as a shell reports it (128 + 15).
EXIT_TERMINATED = 143

#: The demo's handles on the bundled panorama: the bent top edges of the window wall and the
#: television, rectified; a cage that holds the armchair still.
DEMO_HANDLES = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [
        {"kind": "line", "id": "window top", "start": [-4.0, 37.5], "end": [68.0, 36.5]},
        {"kind": "line", "id": "television top", "start": [-83.0, 12.0], "end": [-45.5, 12.0]},
        {"kind": "cage", "id": "armchair", "vertices": [[-28.0, -5.0], [-2.0, -5.0], [-2.0, -50.0], [-28.0, -50.0]]},
    ],
    "options": {"rectify": "all"},
}


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread as Ctrl+C is, so that what is being written is removed on the way out."""


def _on_sigterm(signum: int, frame: object) -> NoReturn:
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM ends the process at once, as by default
    raise _Terminated


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """While the command runs, SIGTERM raises :class:`_Terminated` (in the main thread only: Python's signals go there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


class _FramesFailed(Exception):
    """Some frames of a batch were not warped; each was already reported on its own line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not the whole usage text
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="omniwidget", description="Straighten and edit 360° equirectangular panoramas.")
    parser.add_argument("--version", action="version", version=f"omniwidget {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    quiet = _Parser(add_help=False)
    quiet.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="print nothing on success: no closing line, no progress bar, no notes (warnings and errors still print)",
    )

    warp = sub.add_parser(
        "warp",
        parents=[quiet],
        help="warp panoramas by a handles file or a saved map",
        description="Warp one panorama, many frames alike or a 360° video (the map is computed once), by the handles in a JSON file or a saved map.",
    )
    _add_warp_arguments(warp, "warp")

    straighten = sub.add_parser(
        "straighten",
        parents=[quiet],
        help="level a panorama, find its structure and straighten it in one step",
        description="Level the panorama (its vertical edges), find its structural lines (verticals, the edges where walls meet "
        "floor and ceiling, long building edges; not texture such as tiles or cobbles), choose a set of them that do not cross, "
        "and rectify them all; the handles used can be saved (-H) to change them in the editor. Images, frames and videos as "
        "warp takes them (the lines found in the first image, or a video's middle frame).",
    )
    _add_warp_arguments(straighten, "straighten")

    level = sub.add_parser(
        "level",
        parents=[quiet],
        help="level a panorama taken with a tilted camera",
        description="Find how far the camera was from level (pitch and roll) from the vertical edges in the panorama, "
        "and warp it by the rotation that makes them vertical, as warp does with a handles file's options.up.",
    )
    level.add_argument("input", type=Path, help="equirectangular image (2:1)")
    level.add_argument("-o", "--output", type=Path, required=True, help="the levelled image (.png, .jpg, .tif, .npy)")
    level.add_argument("--map", type=Path, help="also save the inverse map, as warp --map writes it (.npy)")
    level.add_argument("-H", "--handles", type=Path, help="also save the rotation as a handles file (JSON: no handles, options.up where the panorama sees the true vertical)")
    level.add_argument("--width", type=int, help="output width in pixels (even; default: the input's)")
    level.add_argument("--order", choices=("nearest", "bilinear", "bicubic"), default="bilinear", help="resampling (default: bilinear)")
    level.add_argument("--fit", choices=("pad", "stretch"), help="make a non-2:1 input 2:1 first, as for warp (default: refuse it)")

    suggest = sub.add_parser(
        "suggest",
        parents=[quiet],
        help="write a handles file of the straight edges found in a panorama",
        description="Find the straight 3D edges in a panorama and write them as line handles (best first), "
        "to edit or to warp with: omniwidget warp INPUT -H handles.json -o OUTPUT.",
    )
    suggest.add_argument("input", type=Path, help="equirectangular image (2:1)")
    suggest.add_argument("-o", "--output", type=Path, required=True, help="the handles file to write (.json)")
    suggest.add_argument("--max-lines", type=int, default=40, metavar="N", help="at most this many lines, best first (default: 40)")
    suggest.add_argument("--level", action="store_true", help="also level the panorama: the file's options.up set (the lines straightened in the levelled frame)")
    suggest.add_argument("--fit", choices=("pad", "stretch"), help="make a non-2:1 input 2:1 first, as for warp (default: refuse it)")

    demo = sub.add_parser(
        "demo",
        parents=[quiet],
        help="before/after of the bundled panorama",
        description="Rectify lines of the bundled panorama and write the result as it is (after.png), the input (before.png) "
        "and both with the handles drawn (before-handles.png, after-handles.png, and the two stacked in before_after.png).",
    )
    demo.add_argument(
        "-o", "--output-dir", type=Path, default=Path("omniwidget-demo"), help="folder for the pictures (default: ./omniwidget-demo)"
    )

    view = sub.add_parser(
        "view",
        parents=[quiet],
        help="write a perspective still of a panorama, as a 360° viewer shows it",
        description="Render what a 360° viewer shows looking towards a direction: a rectilinear (perspective) still, "
        "north up, by the camera of the editor's look-around view (omniwidget.view).",
    )
    view.add_argument("input", type=Path, help="equirectangular image (2:1)")
    view.add_argument("-o", "--output", type=Path, required=True, help="the still (.png, .jpg, .tif, .webp, .bmp, .npy)")
    view.add_argument("--yaw", type=float, default=0.0, help="longitude of the view's centre, degrees, east positive (default: 0)")
    view.add_argument("--pitch", type=float, default=0.0, help="latitude of the view's centre, degrees in [-90, 90], up positive (default: 0)")
    view.add_argument("--fov", type=float, default=90.0, help="horizontal field of view, degrees, more than 0 and less than 180 (default: 90)")
    view.add_argument("--width", type=int, default=1280, help="width of the still in pixels (default: 1280)")
    view.add_argument("--height", type=int, help="height of the still in pixels (default: the width x 9 / 16)")
    view.add_argument("--order", choices=("nearest", "bilinear", "bicubic"), default="bilinear", help="resampling (default: bilinear)")
    view.add_argument("--fit", choices=("pad", "stretch"), help="make a non-2:1 input 2:1 first, as for warp (default: refuse it)")

    sub.add_parser(
        "schema",
        help="print the JSON Schema of the handles file",
        description="Print the JSON Schema (draft 2020-12) of the handles file, for editors and other programs that write one.",
    )
    for name in ("warp", "straighten", "level"):  # what writes panoramas: their metadata's flags
        if name in sub.choices:
            _add_metadata_arguments(sub.choices[name], name)
    return parser


def _add_metadata_arguments(parser: argparse.ArgumentParser, command: str) -> None:
    """``--no-gpano`` (and ``level``'s ``--pose-only``): the outputs' Photo Sphere XMP."""
    parser.add_argument(
        "--no-gpano",
        action="store_true",
        help="write no Photo Sphere XMP (GPano) into outputs whose input has none (by default it is written: the output is a whole "
        "equirectangular sphere); an input's own is always kept and brought up to date",
    )
    if command == "level":
        parser.add_argument(
            "--pose-only",
            action="store_true",
            help="do not resample: copy the input's bytes with the pitch and roll found written as its GPano pose "
            "(PosePitchDegrees, PoseRollDegrees), which viewers such as Pannellum undo on display (JPEG, PNG or WebP; "
            "the output in the input's format)",
        )


def _output_metadata(args: argparse.Namespace, source: Path, shape: tuple[int, ...], handles: Any = None, levelled: bool = False) -> Any:
    """The metadata an output of ``shape`` made from ``source`` carries (:func:`omniwidget.io.metadata.output_metadata`)."""
    levelled = levelled or (handles is not None and handles.options.up is not None)
    return io_metadata.output_metadata(io_metadata.read_metadata(source), shape[1], shape[0], gpano=not args.no_gpano, levelled=levelled)


def _check_output(path: Path, suffixes: Sequence[str], what: str) -> None:
    if path.suffix.lower() not in suffixes:
        raise ImageError(f"{path}: the {what} must end in {', '.join(suffixes)}")
    if not path.parent.is_dir():
        raise ImageError(f"{path}: the folder {path.parent} does not exist")


def _add_warp_arguments(parser: argparse.ArgumentParser, command: str) -> None:
    """The arguments ``warp`` and ``straighten`` share: inputs, output, sizes, frames and videos; and each one's own."""
    parser.add_argument(
        "input", type=Path, nargs="+", help="equirectangular image(s) (2:1); several: frames of one size; or one 360° video (.mp4, .mov, .mkv, ...)"
    )
    if command == "warp":
        source = parser.add_mutually_exclusive_group(required=True)
        source.add_argument("-H", "--handles", type=Path, help="handles file (JSON: docs/handles-file.md)")
        source.add_argument("--apply-map", type=Path, metavar="MAP", help="a map saved with --map (.npy) instead of handles")
    else:
        parser.add_argument("-H", "--handles", type=Path, help="also save the handles used (JSON): open them in the editor to change them")
        parser.add_argument("--max-lines", type=int, default=40, help="most lines straightened, the best of those found (default: 40)")
        parser.add_argument("--no-level", action="store_true", help="leave the panorama's vertical as it is (default: level it first)")
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="output image (.png, .jpg, .tif, .npy); with several inputs a folder; for a video .mp4, .m4v or .mov",
    )
    parser.add_argument("--width", type=int, help="output width in pixels (even; default: the input's)")
    parser.add_argument("--map", type=Path, help="also save the inverse map: float32 (H, W, 2) input [lon, lat] per output pixel, .npy")
    parser.add_argument("--order", choices=("nearest", "bilinear", "bicubic"), default="bilinear", help="resampling (default: bilinear)")
    parser.add_argument("--workers", type=int, help="threads for many frames (default: CPUs + 1), or resampling a video's frames (default: 2)")
    if command == "warp":
        parser.add_argument(
            "--dask",
            metavar="SCHEDULER",
            help="run each file (each time range of a video) as a task on a Dask cluster: the scheduler's address (tcp://host:8786) or its scheduler "
            'file (.json); the paths must name the same files on every worker (the dask extra: pip install ".[dask]" in a clone)',
        )
    parser.add_argument(
        "--fit",
        choices=("pad", "stretch"),
        help="make a non-2:1 input 2:1 first: pad adds black (transparent) rows above and below a 360°-wide panorama "
        "cropped in latitude, stretch resizes it (default: refuse it)",
    )
    parser.add_argument("--progress", action="store_true", help="show the progress on stderr even when it is not a terminal")
    video = parser.add_argument_group("video", "for a video input (INPUT.mp4 ... -o OUTPUT.mp4); the sound is copied as it is")
    video.add_argument("--codec", help="video encoder (default: libx264; for 10-bit input libx265, else libx264 in 10 bits)")
    video.add_argument("--crf", type=int, help="constant rate factor, lower is better and larger (default: 18 for libx264, 20 for libx265)")
    video.add_argument("--preset", help="encoder speed preset, ultrafast to placebo (default: medium)")
    video.add_argument(
        "--spherical",
        action="store_true",
        help="write spherical-video (360°) metadata even when the input has none (the input's is always carried over)",
    )
    if command == "warp":
        video.add_argument(
            "--segment-seconds",
            type=float,
            metavar="SECONDS",
            help="with --dask: cut each video into time ranges of about this length, one task each, joined without re-encoding (default: 60)",
        )


def _warp_quietly(*args: Any, **kwargs: Any) -> Result:
    """Run a warp; its conflict warnings go to stderr as one line each instead of Python warnings."""
    result = pipeline.warp(*args, warn=False, **kwargs)
    for message in result.warnings:
        print(f"omniwidget: warning: {message}", file=sys.stderr)
    return result


_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".npy")

def _say(args: argparse.Namespace, text: str) -> None:
    """One line of the command's own on stderr (the closing line, a note), unless ``--quiet``."""
    if not args.quiet:
        print(f"omniwidget {args.command}: {text}", file=sys.stderr, flush=True)


def _elapsed(args: argparse.Namespace) -> str:
    """The time since the command started (reading, the work and writing), for the closing line."""
    return f"{time.perf_counter() - args.started:.2f} s"


def _size(image: Any) -> str:
    return f"{image.shape[1]} x {image.shape[0]}"


def _headline(result: Result) -> str:
    """How a warp came out, in a few words: its lines' straightness, its fold-over, its warnings.

    Only what is cheap or already computed: the lines measured as ``Result.quality`` measures
    them (:func:`omniwidget.evaluate.quality.chain_straightness`: densely, through the map that
    placed the pixels), the fold-over the warp found (``result.folds``) and the conflicts it reported
    (``result.warnings``, printed above the closing line), with the handles their problems name
    (``result.problems``).
    """
    parts = []
    lines = quality.chain_straightness(result)
    if lines:
        worst = max(lines)
        shown = not any(math.isnan(v) for v in lines)
        parts.append(f"lines within {max(worst, 0.01):.2g} px" if shown else "a line is not found in the output")
    area = result.folds.area
    parts.append(f"fold-over {100 * area:.2g}% of the sphere" if area > 0 else "fold-over 0")
    if result.warnings:
        named = list(dict.fromkeys(f"handles[{h}]" for p in result.problems for h in p.handles))
        count = len(result.warnings)
        parts.append(f"{count} warning{'s' if count > 1 else ''} above" + (f" ({', '.join(named)})" if named else ""))
    else:
        parts.append("no warnings")
    return ", ".join(parts)


#: What the library's messages say in Python, and the command line's words for it.
_COMMAND_LINE_WORDS = (
    (" (omniwidget warp --fit, or omniwidget.to_equirectangular)", ""),
    ('fit="pad"', "--fit pad"),
    ('fit="stretch"', "--fit stretch"),
    (", or drop it (image[..., :-1])", ""),
)


def _as_command_line(message: str) -> str:
    """A message of the library in the command line's words: the option that fixes it, not the Python argument."""
    for python, command_line in _COMMAND_LINE_WORDS:
        message = message.replace(python, command_line)
    return message


def _quiet_opencv() -> None:
    """Silence OpenCV's own log lines (a decoder's complaints): the one-line error says it, naming the file."""
    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    if logging is not None:
        logging.setLogLevel(logging.LOG_LEVEL_SILENT)


def _refuse_overwrites(args: argparse.Namespace, writes: Sequence[tuple[str, Path | None]]) -> None:
    """Refuse, before any work, an output that names an input, the handles file, the map or another output; then clear its leftovers.

    ``writes`` are the outputs in the order they are written, each with its option (``-o``,
    ``--map``; None: not asked for). The paths are compared as files (symbolic and hard links
    too): one line names both (:func:`omniwidget._files.refuse_overwrites`). Then what killed
    runs left beside the outputs (hidden ``.NAME.*.tmp`` and ``.part`` files no live run holds)
    is removed.
    """
    reads: list[tuple[str, Path]] = [("the input", p) for p in (args.input if isinstance(args.input, list) else [args.input])]
    if args.command == "warp":  # level's -H is one of its outputs
        reads += [(what, p) for what, p in (("the handles file", args.handles), ("the map", args.apply_map)) if p is not None]
    named = [(what, p) for what, p in writes if p is not None]
    refuse_overwrites(reads, named)
    remove_leftovers(*(p for _, p in named))


def _cmd_warp(args: argparse.Namespace) -> None:
    _quiet_opencv()
    if args.map is not None:
        _check_output(args.map, (".npy",), "map file")
    if args.width is not None and (args.width < 2 or args.width % 2):
        raise ImageError(f"--width {args.width}: the width must be even and at least 2")
    if args.workers is not None and args.workers < 1:
        raise ImageError(f"--workers {args.workers}: at least one thread")
    video_only = [f"--{name}" for name in ("codec", "crf", "preset", "spherical") if getattr(args, name) not in (None, False)]
    videos = any(p.suffix.lower() in _VIDEO_SUFFIXES for p in args.input)
    if args.segment_seconds is not None and not (videos and args.dask is not None):
        raise ImageError("--segment-seconds cuts videos for a Dask cluster: give it with --dask and a video input")
    if args.dask is not None:
        _warp_on_dask(args, videos)
    elif videos or args.output.suffix.lower() in _VIDEO_SUFFIXES:
        _warp_video(args)
    elif video_only:
        raise ImageError(f"{video_only[0]} is for a video input (INPUT.mp4 ... -o OUTPUT.mp4)")
    elif len(args.input) == 1 and args.apply_map is None:
        _warp_one(args)
    else:
        _warp_frames(args)


def _warp_one(args: argparse.Namespace) -> None:
    (source,) = args.input
    _check_output(args.output, _IMAGE_SUFFIXES, "output image")
    _refuse_overwrites(args, [("-o", args.output), ("--map", args.map)])
    handles = document_handles.load_handles(args.handles)
    if _in_strips(args, source):
        _warp_in_strips(args, source, handles)
        return
    image = images.read_panorama(source, args.fit, width=args.width, warp=True)  # refused before decoding if the warp cannot fit
    images.check_writable(args.output, image[:0])  # a depth or alpha the format cannot hold is said before the work
    if (args.width or image.shape[1]) > strips.STREAM_WIDTH:  # a format whose header does not say its size
        _warp_in_strips(args, source, handles, image)
        return
    result, outputs = _warped_outputs(args, image, handles, source)
    _write_outputs(outputs)
    _say(args, f"wrote {_written(outputs)} ({_size(result.image)}) in {_elapsed(args)}; {_headline(result)}")


def _write_outputs(outputs: list[tuple[Path, bytes]], handles_path: Path | None = None, handles: Any = None) -> None:
    """Write each ``(path, bytes)``, and with ``handles_path`` the handles document there too (appended to ``outputs``)."""
    if handles_path is not None:
        outputs.append((handles_path, (handles.to_json() + "\n").encode()))
    for path, data in outputs:
        images.write_bytes(path, data)


def _in_strips(args: argparse.Namespace, source: Path) -> bool:
    """Whether the warp is made in strips: its output is wider than STREAM_WIDTH, or its warp in memory would not fit.

    Known from the file's header; a file whose header does not say its size is decided once decoded.
    """
    if source.is_dir():
        return False  # read_panorama says what is wrong with it
    header = images.image_header(source)
    if header is None:
        return False
    if (args.width or max(header.width, header.height)) > strips.STREAM_WIDTH:
        return True
    have = images.available_memory()
    return have is not None and images.memory_needed(source, warp=True, width=args.width) > have


def _warp_in_strips(args: argparse.Namespace, source: Path, handles: Any, image: Any = None) -> None:
    """The warp made in strips (:func:`~omniwidget.app.strips.strips_of_file`), the output and the map written strip by strip.

    ``image``: the panorama already decoded. The image is written before the map (each whole or not at all): a failure
    writing the map leaves the image.
    """
    with app_strips.strips_of_file(source, handles, width=args.width, order=args.order, fit=args.fit, image=image, output=args.output) as made:
        for message in made.result.warnings:
            print(f"omniwidget: warning: {message}", file=sys.stderr)
        height, width = made.shape[:2]
        show = args.progress or (sys.stderr.isatty() and not args.quiet)
        progress = (lambda rows: _progress_bar(rows, height, "rows")) if show else None
        meta = _output_metadata(args, source, made.shape, handles)
        images.write_image_strips(args.output, made.shape, made.dtype, made.image_strips(), progress=progress, meta=meta)
        written = [args.output]
        if args.map is not None:
            images.write_image_strips(args.map, (height, width, 2), np.float32, made.map_strips())
            written.append(args.map)
    names = " and ".join(str(p) for p in written)
    _say(args, f"wrote {names} ({width} x {height}, in strips) in {_elapsed(args)}; {_headline(made.result)} (measured {strips.MAP_WIDTH} wide)")


def _written(outputs: Sequence[tuple[Path, bytes]]) -> str:
    """The files written, for the closing line: ``a.png``, ``a.png and m.npy``, ``a.png, m.npy and h.json``."""
    names = [str(path) for path, _ in outputs]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def _warped_outputs(args: argparse.Namespace, image: Any, handles: Any, source: Path | None = None) -> tuple[Result, list[tuple[Path, bytes]]]:
    """``image`` warped by ``handles``, and the output image (with ``--map`` the inverse map too) encoded, not yet written.

    ``source``: the file ``image`` was read from, whose metadata the output carries (brought up to date).
    """
    result = _warp_quietly(image, handles, width=args.width, order=args.order)
    # all encoded before any is written: a failure leaves no output at all
    meta = _output_metadata(args, source, result.image.shape, handles) if source is not None else None
    outputs = [(args.output, images.encode_image(args.output, result.image, meta))]
    if args.map is not None:
        outputs.append((args.map, images.encode_image(args.map, result.inverse_map())))  # .npy: the float32 array as it is
    return result, outputs


def _frame_outputs(args: argparse.Namespace) -> list[Path]:
    """Where each frame goes: ``-o`` itself for one input, else ``-o/<the input's name>``; checked before any work."""
    inputs = args.input
    if len(inputs) == 1:
        outputs = [args.output]
        _check_output(args.output, _IMAGE_SUFFIXES, "output image")
    else:
        if args.output.suffix.lower() in _IMAGE_SUFFIXES or (args.output.exists() and not args.output.is_dir()):
            raise ImageError(f"{args.output}: with {len(inputs)} inputs, -o names a folder for their outputs")
        if not args.output.parent.is_dir():
            raise ImageError(f"{args.output}: the folder {args.output.parent} does not exist")
        names = [p.name for p in inputs]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ImageError(f"inputs share the file name {twice[0]}: their outputs in {args.output} would overwrite each other")
        outputs = [args.output / n for n in names]
        unwritable = next((o for o in outputs if o.suffix.lower() not in _IMAGE_SUFFIXES), None)
        if unwritable is not None:
            raise ImageError(f"{unwritable}: outputs keep their input's name, and the output must end in {', '.join(_IMAGE_SUFFIXES)}")
    _refuse_overwrites(args, [*((("-o" if len(inputs) == 1 else "the output"), o) for o in outputs), ("--map", args.map)])
    return outputs


def _progress_bar(done: int, total: int, what: str = "frames") -> None:
    width = 30
    filled = round(width * done / total)
    end = "\n" if done == total else ""
    print(f"\romniwidget: [{'#' * filled}{'.' * (width - filled)}] {done}/{total} {what}", end=end, file=sys.stderr, flush=True)


def _warp_frames(args: argparse.Namespace) -> None:
    outputs = _frame_outputs(args)
    handles = document_handles.load_handles(args.handles) if args.handles is not None else None
    saved = frames.load_map(args.apply_map) if args.apply_map is not None else None
    first = images.read_panorama(args.input[0], args.fit, width=args.width, warp=True, reduce=False)  # frames share one size: all whole
    images.check_format(outputs[0], first[:0])  # the folder may not exist yet
    start = time.perf_counter()
    result: Result | None = None
    if saved is not None:
        if args.width is not None and args.width != saved.shape[1]:
            raise ImageError(f"--width {args.width}: the map {args.apply_map} makes frames {saved.shape[1]} wide")
        inverse_map = saved
    else:
        result = _warp_quietly(first, handles, width=args.width, order=args.order)
        inverse_map = result.inverse_map()
    coordinates = app_frames.map_coordinates(inverse_map, first.shape[1])
    map_seconds = time.perf_counter() - start
    if args.map is not None:
        images.write_image(args.map, inverse_map)
    if len(outputs) > 1:
        args.output.mkdir(exist_ok=True)
    progress = _progress_bar if len(outputs) > 1 and (args.progress or (sys.stderr.isatty() and not args.quiet)) else None
    report = app_frames.warp_frames(
        args.input,
        outputs,
        coordinates,
        first.shape[:2],
        app_frames.FrameSettings(order=args.order, fit=args.fit, gpano=not args.no_gpano, levelled=handles is not None and handles.options.up is not None),
        workers=args.workers,
        progress=progress,
    )
    h, w = coordinates.shape[:2]
    where = str(outputs[0]) if len(outputs) == 1 else f"{args.output}{'' if str(args.output).endswith('/') else '/'}"
    also = f" and {args.map}" if args.map is not None else ""
    how = _headline(result) if result is not None else f"by the map {args.apply_map}"
    _say(
        args,
        f"wrote {len(report.written)} of {len(outputs)} frame(s) to {where}{also} ({w} x {h}) in {_elapsed(args)}: "
        f"{report.fps:.1f} frames per second (reading and writing included; the map took {map_seconds:.2f} s); {how}",
    )
    if report.failed:
        for _, why in report.failed:
            print(f"omniwidget warp: error: {_as_command_line(why)}", file=sys.stderr)
        raise _FramesFailed(f"{len(report.failed)} of {len(args.input)} frames were not warped (see above)")


def _check_scheduler(value: str) -> None:
    """``--dask``'s value names a scheduler file that is there, or an address with a port (said before any work)."""
    if value.endswith(".json"):
        if not Path(value).is_file():
            raise ImageError(f"--dask {value}: no scheduler file there (dask scheduler --scheduler-file {value} writes it)")
    elif not re.search(r":\d+$", value):
        raise ImageError(f"--dask {value}: give the scheduler's address with its port (tcp://host:8786) or its scheduler file (.json)")


def _warp_on_dask(args: argparse.Namespace, videos: bool) -> None:
    """``--dask``: each file a task on the cluster, each video's time ranges tasks (:func:`omniwidget.app.batch.warp_files`); the workers read and write the files."""
    if args.map is not None:
        raise ImageError("--map with --dask: save the map on this machine first (omniwidget warp FRAME -H ... --map MAP.npy), then --apply-map MAP.npy")
    if args.workers is not None:
        raise ImageError("--workers sets threads on this machine; with --dask the cluster's workers run the files (dask worker --nthreads)")
    video_only = [f"--{name}" for name in ("codec", "crf", "preset", "spherical") if getattr(args, name) not in (None, False)]
    if video_only and not videos:
        raise ImageError(f"{video_only[0]} is for a video input (INPUT.mp4 ... -o OUTPUT.mp4)")
    _check_scheduler(args.dask)
    if videos and len(args.input) > 1 and (args.output.suffix.lower() in _IMAGE_SUFFIXES + _VIDEO_SUFFIXES or args.output.is_file()):
        raise ImageError(f"{args.output}: with {len(args.input)} inputs, -o names a folder for their outputs")
    # images alone are checked here as without --dask; with a video, the batch checks each output's suffix
    outputs: Any = _frame_outputs(args) if not videos else ([args.output] if len(args.input) == 1 else args.output)
    if videos:
        each = outputs if len(args.input) == 1 else [args.output / p.name for p in args.input]
        _refuse_overwrites(args, [(("-o" if len(each) == 1 else "the output"), o) for o in each])
    if not videos and len(outputs) > 1:
        args.output.mkdir(exist_ok=True)
    handles = document_handles.load_handles(args.handles) if args.handles is not None else None
    saved = frames.load_map(args.apply_map) if args.apply_map is not None else None
    if saved is not None and args.width is not None and args.width != saved.shape[1]:
        raise ImageError(f"--width {args.width}: the map {args.apply_map} makes frames {saved.shape[1]} wide")
    progress = _progress_bar if len(args.input) > 1 and (args.progress or (sys.stderr.isatty() and not args.quiet)) else None
    options: dict[str, Any] = {"codec": args.codec, "crf": args.crf, "preset": args.preset, "spherical": True if args.spherical else None}
    if args.segment_seconds is not None:
        if not args.segment_seconds > 0:
            raise ImageError(f"--segment-seconds {args.segment_seconds:g}: a time range lasts more than 0 seconds")
        options["segment_seconds"] = args.segment_seconds
    try:
        report = batch.warp_files(
            args.input,
            outputs,
            handles=handles,
            map=saved,
            client=args.dask,
            width=args.width,
            order=args.order,
            fit=args.fit,
            progress=progress,
            **options,
        )
    except ImportError as exc:
        raise OmniwidgetError(str(exc)) from None
    for message in report.warnings:
        print(f"omniwidget: warning: {message}", file=sys.stderr)
    how = "each worker computed the map, not measured here" if handles is not None else f"by the map {args.apply_map}"
    done = f"wrote {len(report.written)} of {len(report.files)} file(s) to {args.output} in {_elapsed(args)}"
    _say(args, f"{done}; {report.summary().splitlines()[0]}; {how}")
    if report.failed:
        for _, why in report.failed:
            print(f"omniwidget warp: error: {_as_command_line(why)}", file=sys.stderr)
        raise _FramesFailed(f"{len(report.failed)} of {len(report.files)} files were not warped (see above)")


#: Names the command line reads as videos (omniwidget.io.video.INPUT_SUFFIXES, without importing it).
_VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv", ".webm", ".avi", ".mts", ".m2ts", ".ts")


class _VideoProgress:
    """The progress of a video on stderr: a bar redrawn in place on a terminal, else a line every few seconds."""

    def __init__(self, tty: bool) -> None:
        self.tty = tty
        self.start = time.perf_counter()
        self.shown = -1.0

    def __call__(self, done: int, total: int | None) -> None:
        now = time.perf_counter()
        complete = total is not None and done >= total
        if not (done == 1 or complete or now - self.shown >= (0.1 if self.tty else 1.0)):
            return
        self.shown = now
        fps = done / (now - self.start) if now > self.start else 0.0
        if total:
            width = 30
            filled = min(width, round(width * done / total))
            left = f", {_clock((total - done) / fps)} left" if fps > 0 and not complete else ""
            text = f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total} frames, {fps:.1f} fps{left}"
        else:
            text = f"{done} frames, {fps:.1f} fps"
        if self.tty:
            print(f"\romniwidget: {text}\033[K", end="", file=sys.stderr, flush=True)
        else:
            print(f"omniwidget: {text}", file=sys.stderr, flush=True)

    def finish(self) -> None:
        """End the bar's line on a terminal, so that what follows starts on a line of its own."""
        if self.tty and self.shown >= 0:
            print(file=sys.stderr, flush=True)


def _clock(seconds: float) -> str:
    seconds = max(0, round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}" if seconds >= 3600 else f"{seconds // 60}:{seconds % 60:02d}"


def _warp_video(args: argparse.Namespace) -> None:
    """One video to one video: the map once (from the first frame, or --apply-map), then every frame by it (omniwidget.app.video)."""
    if len(args.input) != 1:
        raise ImageError("a video is warped on its own: omniwidget warp INPUT.mp4 (-H handles.json | --apply-map MAP.npy) -o OUTPUT.mp4")
    (source,) = args.input
    if source.suffix.lower() not in _VIDEO_SUFFIXES:
        raise ImageError(f"{args.output}: a video output needs a video input ({', '.join(_VIDEO_SUFFIXES)}), and {source} is not one")
    if args.fit is not None:
        raise ImageError("--fit is not for videos")
    _check_output(args.output, io_video.OUTPUT_SUFFIXES, "output video")
    _refuse_overwrites(args, [("-o", args.output), ("--map", args.map)])
    if args.width is not None and args.width % 4:
        raise ImageError(f"--width {args.width}: a video's width must be a multiple of 4 (4:2:0 video has even sizes)")
    start = time.perf_counter()
    result: Result | None = None
    if args.apply_map is not None:
        inverse_map = frames.load_map(args.apply_map)
        if args.width is not None and args.width != inverse_map.shape[1]:
            raise ImageError(f"--width {args.width}: the map {args.apply_map} makes frames {inverse_map.shape[1]} wide")
    else:
        handles = document_handles.load_handles(args.handles)
        with io_video.VideoReader(source) as video:  # refuses what is no 360° video before any work
            first = video.read_at(video.info.start)
        result = _warp_quietly(first, handles, width=args.width, order=args.order)
        inverse_map = result.inverse_map()
    map_seconds = time.perf_counter() - start
    progress = _VideoProgress(sys.stderr.isatty()) if args.progress or (sys.stderr.isatty() and not args.quiet) else None
    try:
        report = app_video.warp_video(
            source,
            args.output,
            inverse_map,
            settings=app_video.VideoSettings(
                order=args.order, codec=args.codec, crf=args.crf, preset=args.preset, spherical=True if args.spherical else None, workers=args.workers
            ),
            progress=progress,
        )
    finally:
        if progress is not None:
            progress.finish()
    if args.map is not None:
        images.write_image(args.map, inverse_map)
    for stream in report.dropped:
        _say(args, f"note: not copied: {stream}")
    w, h = report.size
    settings = ", ".join(f"{k} {v}" for k, v in report.options.items() if k in ("crf", "preset"))
    sound = f"{len(report.audio)} audio stream(s) copied" if report.audio else "no audio"
    metadata = "spherical metadata written" if report.spherical is not None else "no spherical metadata (--spherical writes it)"
    also = f" and {args.map}" if args.map is not None else ""
    how = _headline(result) if result is not None else f"by the map {args.apply_map}"
    _say(
        args,
        f"wrote {args.output}{also} ({report.frames} frame(s) of {w} x {h}) in {_elapsed(args)}: {report.fps:.1f} frames per second "
        f"({report.codec} {report.pix_fmt}{', ' + settings if settings else ''}; {sound}; {metadata}; "
        f"the map took {map_seconds + report.map_seconds:.2f} s); {how}",
    )


def _cmd_straighten(args: argparse.Namespace) -> None:
    """``omniwidget straighten``: level, find the structure, rectify it (:func:`omniwidget.straighten`), as ``warp`` writes its outputs.

    The lines are found on the first input (a video's middle frame) at the detector's width,
    and checked there by a warp (lines that give way are left out); the handles are then
    warped onto every input as ``warp -H`` does, at full size, frames and videos included.
    """
    _quiet_opencv()
    if args.max_lines < 1:
        raise ImageError(f"--max-lines {args.max_lines}: at least one line")
    if args.handles is not None:
        _check_output(args.handles, (".json",), "handles file")
    saved_handles, args.handles = args.handles, None
    _refuse_overwrites(args, [("-o", args.output), ("--map", args.map), ("-H", saved_handles)])
    first = args.input[0]
    if io_video.is_video_path(first):
        with io_video.VideoReader(first) as video:  # refuses what is no 360° video before any work
            seen = video.read(len(video) // 2)
    else:
        seen = images.read_panorama(first, args.fit, width=detect.DETECT_WIDTH)  # a JPEG twice as wide or more is decoded reduced
    seen = seen if seen.shape[1] <= detect.DETECT_WIDTH else _reduced(seen, detect.DETECT_WIDTH)
    done = app_straighten.straighten(seen, max_lines=args.max_lines, level=not args.no_level)
    _say(args, f"{done.structure.summary()} (found {seen.shape[1]} wide)")
    text = done.handles.to_json() + "\n"
    with tempfile.TemporaryDirectory(prefix="omniwidget-straighten-") as folder:
        args.handles, args.apply_map, args.dask, args.segment_seconds = Path(folder) / "handles.json", None, None, None
        args.handles.write_text(text)
        _cmd_warp(args)
    if saved_handles is not None:
        images.write_bytes(saved_handles, text.encode())


def _reduced(frame: Any, width: int) -> Any:
    """A frame resized to ``width`` by area averaging (the detector's input)."""
    return cv2.resize(frame, (width, width // 2), interpolation=cv2.INTER_AREA)


def _cmd_level(args: argparse.Namespace) -> None:
    """``omniwidget level``: the camera's tilt from the vertical edges, undone by the levelling turn (``options.up``, as warp does)."""
    _quiet_opencv()
    for path, suffixes, what in ((args.output, _IMAGE_SUFFIXES, "output image"), (args.map, (".npy",), "map file"), (args.handles, (".json",), "handles file")):
        if path is not None:
            _check_output(path, suffixes, what)
    _refuse_overwrites(args, [("-o", args.output), ("--map", args.map), ("-H", args.handles)])
    if args.width is not None and (args.width < 2 or args.width % 2):
        raise ImageError(f"--width {args.width}: the width must be even and at least 2")
    if args.pose_only:
        _check_pose_only(args)
    image = images.read_panorama(args.input, args.fit, width=args.width, warp=True)
    images.check_writable(args.output, image[:0])  # a depth or alpha the format cannot hold is said before the work
    found = detect.level(image)  # too few vertical edges: a LevelError, one line, nothing written
    handles = found.handles()
    if args.pose_only:
        _write_pose(args, found, handles)
        return
    result, outputs = _warped_outputs(args, image, handles, args.input)
    _write_outputs(outputs, args.handles, handles)
    _say(
        args,
        f"wrote {_written(outputs)} ({_size(result.image)}) in {_elapsed(args)}; levelled by pitch {found.pitch:+.2f}°, "
        f"roll {found.roll:+.2f}° (tilt {found.tilt:.2f}°) from {len(found.edges)} vertical edges; {_headline(result)}",
    )


def _check_pose_only(args: argparse.Namespace) -> None:
    """``level --pose-only`` refused before any work where it cannot be: options that resample, another format."""
    for name in ("map", "width", "fit"):
        if getattr(args, name) is not None:
            raise ImageError(f"--pose-only writes no pixels: --{name} has no meaning with it")
    header = images.image_header(args.input)
    kind = header.format if header is not None else None
    if kind not in ("JPEG", "PNG", "WebP"):
        raise ImageError(f"{args.input}: --pose-only writes the pose into a JPEG, PNG or WebP file; this is {kind or 'neither'}")
    suffixes = {"JPEG": (".jpg", ".jpeg"), "PNG": (".png",), "WebP": (".webp",)}[kind]
    if args.output.suffix.lower() not in suffixes:
        raise ImageError(f"{args.output}: --pose-only copies the {kind} input as it is; name the output {' or '.join(suffixes)}")


def _write_pose(args: argparse.Namespace, found: Any, handles: Any) -> None:
    """``level --pose-only``: the input's bytes, its XMP's GPano pose set to the pitch and roll found (nothing resampled)."""
    data = args.input.read_bytes()
    header = images.image_header(args.input)
    width, height = (header.width, header.height) if header is not None else (0, 0)
    meta = io_metadata.read_metadata(data)
    old = meta.gpano
    angles = found.pose()
    pose = io_metadata.Pose(pitch=angles["PosePitchDegrees"], roll=angles["PoseRollDegrees"])
    if old is not None and old.full_width > 0:  # its own geometry kept (a part of a sphere stays one), only the pose changes
        xmp = io_metadata.replace_xmp(meta.xmp, replace(old, pose=io_metadata.Pose(old.pose.heading, pose.pitch, pose.roll)))
    else:
        xmp = io_metadata.output_metadata(meta, width, height, gpano=True, pose=pose).xmp or b""
    outputs = [(args.output, io_metadata.with_xmp(data, xmp))]
    _write_outputs(outputs, args.handles, handles)
    _say(
        args,
        f"wrote {_written(outputs)} (the input's pixels, not resampled) in {_elapsed(args)}; its GPano pose: pitch {found.pitch:+.2f}°, "
        f"roll {found.roll:+.2f}° (tilt {found.tilt:.2f}°) from {len(found.edges)} vertical edges",
    )


def _cmd_suggest(args: argparse.Namespace) -> None:
    """``omniwidget suggest``: a handles file of line handles along the structure found (best first: :func:`~omniwidget.detect.structure.choose_structure`)."""
    _quiet_opencv()
    _check_output(args.output, (".json",), "handles file")
    _refuse_overwrites(args, [("-o", args.output)])
    if args.max_lines < 1:
        raise ImageError(f"--max-lines {args.max_lines}: at least one line")
    # the lines are found at DETECT_WIDTH at most: a JPEG at least twice as wide is decoded reduced (libjpeg's DCT
    # scaling, an average over each block), suggest_lines takes it the rest of the way
    image = images.read_panorama(args.input, args.fit, width=detect.DETECT_WIDTH)
    every = detect.suggest_lines(image, max_lines=None, structure=False)  # all of them: --level looks among every edge
    found = detect.level(image, suggestions=every) if args.level else None  # too few vertical edges: a LevelError, nothing written
    width = min(int(image.shape[1]), detect.DETECT_WIDTH)  # the width the lines were found at
    chosen = structure.choose_structure(every, None if found is None else found.up, width=width, max_lines=args.max_lines, image=image)
    handles = detect.suggestions_to_handles(chosen.kept)
    note = ""
    if found is not None:
        handles = detect.level_document(handles, found)
        note = f"; levelled (options.up): pitch {found.pitch:+.2f}°, roll {found.roll:+.2f}° from {len(found.edges)} vertical edges"
    text = handles.to_json() + "\n"
    document_handles.Handles.from_json(text)  # what is written is what the loader reads back
    images.write_bytes(args.output, text.encode())
    lines = sum(1 for h in handles.handles if h.kind == "line")
    more = f", the structure among {len(every)} found" if len(every) > lines else ""
    _say(args, f"wrote {args.output} ({lines} line(s){more}{note}) in {_elapsed(args)}")


def _cmd_demo(args: argparse.Namespace) -> None:
    """``omniwidget demo``: the bundled panorama warped by :data:`DEMO_HANDLES`, as it is and with the handles drawn apart.

    ``after.png`` is the result as ``omniwidget.warp`` gives it and ``before.png`` the input,
    nothing drawn on either; ``before-handles.png`` and ``after-handles.png`` draw the handles
    (:func:`omniwidget.io.draw.draw_handles`: on the input where they were marked, on the
    result where their maps put them), and ``before_after.png`` stacks those two.
    """
    out = args.output_dir
    out.mkdir(parents=True, exist_ok=True)
    image = omniwidget_data.sample_image()
    handles = document_handles.Handles.from_dict(DEMO_HANDLES)
    result = _warp_quietly(image, handles)
    before = draw.draw_handles(image, handles, stage="input")
    after = draw.draw_handles(result.image, handles, stage="output")
    gap = np.full((8, image.shape[1], 3), 255, np.uint8)
    pictures = {
        "before.png": image,  # the bundled panorama as it is
        "after.png": result.image,  # the result as it is, nothing drawn on it
        "before-handles.png": before,
        "after-handles.png": after,
        "before_after.png": np.concatenate([before, gap, after]),
    }
    document_handles.save_handles(handles, out / "handles.json")
    for name, picture in pictures.items():
        images.write_image(out / name, picture)
    _say(
        args,
        f"wrote {out / 'after.png'} ({_size(result.image)}), the handles drawn apart ({', '.join(list(pictures)[2:])}), "
        f"before.png and handles.json in {_elapsed(args)}; {_headline(result)}",
    )


def _cmd_view(args: argparse.Namespace) -> None:
    """``omniwidget view``: a perspective still of a panorama (:func:`omniwidget.raster.perspective.view`), the camera checked before any work."""
    _quiet_opencv()
    try:
        yaw, pitch, fov = perspective.check_view(args.yaw, args.pitch, args.fov)
    except ValueError as exc:
        raise ImageError(f"--{exc}") from None
    for name in ("width", "height"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ImageError(f"--{name} {value}: at least one pixel")
    _check_output(args.output, _IMAGE_SUFFIXES, "output image")
    _refuse_overwrites(args, [("-o", args.output)])
    # the still's centre has focal pixels a radian: a panorama of 2 pi focal pixels is as sharp there (and the view is
    # sharpest at its centre), so a JPEG at least twice that wide is decoded reduced (libjpeg's DCT scaling, an average)
    focal = args.width / (2 * math.tan(math.radians(fov) / 2))
    image = images.read_panorama(args.input, args.fit, width=math.ceil(2 * math.pi * focal))
    images.check_writable(args.output, image[:0])  # a depth or alpha the format cannot hold is said before the work
    still = perspective.view(image, yaw=yaw, pitch=pitch, fov=fov, width=args.width, height=args.height, order=args.order)
    images.write_bytes(args.output, images.encode_image(args.output, still.image))
    _say(args, f"wrote {args.output} ({_size(still.image)}) looking at yaw {yaw:g}°, pitch {pitch:g}°, {fov:g}° across in {_elapsed(args)}")


def _cmd_schema(args: argparse.Namespace) -> None:

    print(json.dumps(schema.handles_schema(), indent=2))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = _parser().parse_args(argv)
    args.started = time.perf_counter()
    try:
        with _sigterm_as_interrupt():
            commands = {"warp": _cmd_warp, "straighten": _cmd_straighten, "level": _cmd_level, "suggest": _cmd_suggest, "demo": _cmd_demo}
            {**commands, "view": _cmd_view, "schema": _cmd_schema}[args.command](args)
    except OmniwidgetError as exc:
        print(f"omniwidget {args.command}: error: {_as_command_line(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"omniwidget {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except _FramesFailed as exc:
        print(f"omniwidget {args.command}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print(f"omniwidget {args.command}: error: not enough memory for this image (try a smaller --width)", file=sys.stderr)
        return EXIT_BAD_INPUT
    except _Terminated:  # SIGTERM: as Ctrl+C, the temporary files removed on the way out
        print(f"omniwidget {args.command}: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:  # Ctrl+C: outputs are written whole or not at all, so none is left half-written
        newline = "\n" if sys.stderr.isatty() else ""  # the terminal has echoed ^C
        print(f"{newline}omniwidget {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return 0


if __name__ == "__main__":
    sys.exit(main())
