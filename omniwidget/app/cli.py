"""The command line: ``omniwidget warp`` and ``omniwidget demo``.

Bad input of any kind gives one line on stderr saying what and where, exit status 2, no
traceback and no output file. Outputs are written whole (temporary file, then rename).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._version import __version__

if TYPE_CHECKING:
    from ..raster.pipeline import Result

EXIT_BAD_INPUT = 2

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


class _FramesFailed(Exception):
    """Some frames of a batch were not warped; each was already reported on its own line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, not the whole usage text
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="omniwidget", description="Straighten and edit 360° equirectangular panoramas.")
    parser.add_argument("--version", action="version", version=f"omniwidget {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    warp = sub.add_parser(
        "warp",
        help="warp panoramas by a handles file or a saved map",
        description="Warp one panorama, or many frames alike (the map is computed once), by the handles in a JSON file or a saved map.",
    )
    warp.add_argument("input", type=Path, nargs="+", help="equirectangular image(s) (2:1); several: frames of one size")
    source = warp.add_mutually_exclusive_group(required=True)
    source.add_argument("-H", "--handles", type=Path, help="handles file (JSON, see the README)")
    source.add_argument("--apply-map", type=Path, metavar="MAP", help="a map saved with --map (.npy) instead of handles")
    warp.add_argument(
        "-o", "--output", type=Path, required=True, help="output image (.png, .jpg, .tif, .npy); with several inputs a folder"
    )
    warp.add_argument("--width", type=int, help="output width in pixels (even; default: the input's)")
    warp.add_argument("--map", type=Path, help="also save the inverse map: float32 (H, W, 2) input [lon, lat] per output pixel, .npy")
    warp.add_argument("--order", choices=("nearest", "bilinear", "bicubic"), default="bilinear", help="resampling (default: bilinear)")
    warp.add_argument("--workers", type=int, help="threads for many frames (default: CPUs + 1)")
    warp.add_argument(
        "--fit",
        choices=("pad", "stretch"),
        help="make a non-2:1 input 2:1 first: pad adds black (transparent) rows above and below a 360°-wide panorama "
        "cropped in latitude, stretch resizes it (default: refuse it)",
    )

    demo = sub.add_parser(
        "demo", help="before/after of the bundled panorama", description="Rectify lines of the bundled panorama and write a before/after."
    )
    demo.add_argument(
        "-o", "--output-dir", type=Path, default=Path("omniwidget-demo"), help="folder for the pictures (default: ./omniwidget-demo)"
    )
    return parser


def _check_output(path: Path, suffixes: Sequence[str], what: str) -> None:
    from ..errors import ImageError

    if path.suffix.lower() not in suffixes:
        raise ImageError(f"{path}: the {what} must end in {', '.join(suffixes)}")
    if not path.parent.is_dir():
        raise ImageError(f"{path}: the folder {path.parent} does not exist")


def _warp_quietly(*args: Any, **kwargs: Any) -> Result:
    """Run a warp; its conflict warnings go to stderr as one line each instead of Python warnings."""
    from ..raster.pipeline import warp

    result = warp(*args, warn=False, **kwargs)
    for message in result.warnings:
        print(f"omniwidget: warning: {message}", file=sys.stderr)
    return result


_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".npy")


def _quiet_opencv() -> None:
    """Silence OpenCV's own log lines (a decoder's complaints): the one-line error says it, naming the file."""
    import cv2

    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    if logging is not None:
        logging.setLogLevel(logging.LOG_LEVEL_SILENT)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def _cmd_warp(args: argparse.Namespace) -> None:
    from ..errors import ImageError

    _quiet_opencv()
    if args.map is not None:
        _check_output(args.map, (".npy",), "map file")
    if args.width is not None and (args.width < 2 or args.width % 2):
        raise ImageError(f"--width {args.width}: the width must be even and at least 2")
    if args.workers is not None and args.workers < 1:
        raise ImageError(f"--workers {args.workers}: at least one thread")
    if len(args.input) == 1 and args.apply_map is None:
        _warp_one(args)
    else:
        _warp_frames(args)


def _warp_one(args: argparse.Namespace) -> None:
    from ..document.handles import load_handles
    from ..errors import ImageError
    from ..io.images import check_writable, encode_image, read_panorama, write_bytes

    (source,) = args.input
    if _same_file(args.output, source):
        raise ImageError(f"{args.output}: the output would overwrite the input; choose another file")
    _check_output(args.output, _IMAGE_SUFFIXES, "output image")
    handles = load_handles(args.handles)
    image = read_panorama(source, args.fit)
    check_writable(args.output, image[:0])  # a depth or alpha the format cannot hold is said before the work
    result = _warp_quietly(image, handles, width=args.width, order=args.order)
    # both encoded before either is written: a failure leaves no output at all
    outputs = [(args.output, encode_image(args.output, result.image))]
    if args.map is not None:
        outputs.append((args.map, encode_image(args.map, result.inverse_map())))  # .npy: the float32 array as it is
    for path, data in outputs:
        write_bytes(path, data)


def _frame_outputs(args: argparse.Namespace) -> list[Path]:
    """Where each frame goes: ``-o`` itself for one input, else ``-o/<the input's name>``; checked before any work."""
    from ..errors import ImageError

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
    sources = {p.resolve() for p in inputs}
    clash = next((o for o in outputs if o.resolve() in sources or any(_same_file(o, i) for i in inputs)), None)
    if clash is not None:
        raise ImageError(f"{clash}: the output would overwrite an input; choose another folder")
    return outputs


def _progress_bar(done: int, total: int) -> None:
    width = 30
    filled = round(width * done / total)
    end = "\n" if done == total else ""
    print(f"\romniwidget: [{'#' * filled}{'.' * (width - filled)}] {done}/{total} frames", end=end, file=sys.stderr, flush=True)


def _warp_frames(args: argparse.Namespace) -> None:
    from ..document.handles import load_handles
    from ..errors import ImageError
    from ..io.frames import load_map, map_coordinates, warp_frames
    from ..io.images import check_format, read_panorama, write_image

    outputs = _frame_outputs(args)
    handles = load_handles(args.handles) if args.handles is not None else None
    saved = load_map(args.apply_map) if args.apply_map is not None else None
    first = read_panorama(args.input[0], args.fit)
    check_format(outputs[0], first[:0])  # the folder may not exist yet
    start = time.perf_counter()
    if saved is not None:
        if args.width is not None and args.width != saved.shape[1]:
            raise ImageError(f"--width {args.width}: the map {args.apply_map} makes frames {saved.shape[1]} wide")
        inverse_map = saved
    else:
        inverse_map = _warp_quietly(first, handles, width=args.width, order=args.order).inverse_map()
    coordinates = map_coordinates(inverse_map, first.shape[1])
    map_seconds = time.perf_counter() - start
    if args.map is not None:
        write_image(args.map, inverse_map)
    if len(outputs) > 1:
        args.output.mkdir(exist_ok=True)
    progress = _progress_bar if len(outputs) > 1 and sys.stderr.isatty() else None
    report = warp_frames(
        args.input, outputs, coordinates, first.shape[:2], order=args.order, workers=args.workers, progress=progress, fit=args.fit
    )
    h, w = coordinates.shape[:2]
    print(
        f"warped {len(report.written)} frame(s) to {w} x {h} in {report.seconds:.2f} s: {report.fps:.1f} frames per second "
        f"(reading and writing included; the map took {map_seconds:.2f} s)"
    )
    if report.failed:
        for _, why in report.failed:
            print(f"omniwidget warp: error: {why}", file=sys.stderr)
        raise _FramesFailed(f"{len(report.failed)} of {len(args.input)} frames were not warped (see above)")


def _cmd_demo(args: argparse.Namespace) -> None:
    import numpy as np

    from ..data import sample_image
    from ..document.handles import Handles, save_handles
    from ..io.draw import draw_handles
    from ..io.images import write_image

    out = args.output_dir
    out.mkdir(parents=True, exist_ok=True)
    image = sample_image()
    handles = Handles.from_dict(DEMO_HANDLES)
    start = time.perf_counter()
    result = _warp_quietly(image, handles)
    seconds = time.perf_counter() - start
    before = draw_handles(image, handles, stage="input")
    after = draw_handles(result.image, handles, stage="output")
    gap = np.full((8, image.shape[1], 3), 255, np.uint8)
    save_handles(handles, out / "handles.json")
    write_image(out / "before.png", before)
    write_image(out / "after.png", after)
    write_image(out / "before_after.png", np.concatenate([before, gap, after]))
    print(f"rectified {len(handles)} handle(s) in {seconds:.3f} s; wrote {out}/before.png, after.png, before_after.png, handles.json")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    from ..errors import OmniwidgetError

    args = _parser().parse_args(argv)
    try:
        {"warp": _cmd_warp, "demo": _cmd_demo}[args.command](args)
    except OmniwidgetError as exc:
        print(f"omniwidget {args.command}: error: {exc}", file=sys.stderr)
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
