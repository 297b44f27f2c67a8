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

from ._version import __version__

if TYPE_CHECKING:
    from .core.pipeline import Result

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


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, not the whole usage text
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="omniwidget", description="Straighten and edit 360° equirectangular panoramas.")
    parser.add_argument("--version", action="version", version=f"omniwidget {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    warp = sub.add_parser("warp", help="warp a panorama by a handles file", description="Warp a panorama by the handles in a JSON file.")
    warp.add_argument("input", type=Path, help="equirectangular image (2:1)")
    warp.add_argument("-H", "--handles", type=Path, required=True, help="handles file (JSON, see the README)")
    warp.add_argument("-o", "--output", type=Path, required=True, help="output image (.png, .jpg, .tif, .npy)")
    warp.add_argument("--width", type=int, help="output width in pixels (even; default: the input's)")
    warp.add_argument("--map", type=Path, help="also save the inverse map: float32 (H, W, 2) input [lon, lat] per output pixel, .npy")
    warp.add_argument("--order", choices=("nearest", "bilinear", "bicubic"), default="bilinear", help="resampling (default: bilinear)")

    demo = sub.add_parser(
        "demo", help="before/after of the bundled panorama", description="Rectify lines of the bundled panorama and write a before/after."
    )
    demo.add_argument(
        "-o", "--output-dir", type=Path, default=Path("omniwidget-demo"), help="folder for the pictures (default: ./omniwidget-demo)"
    )
    return parser


def _check_output(path: Path, suffixes: Sequence[str], what: str) -> None:
    from .core.errors import ImageError

    if path.suffix.lower() not in suffixes:
        raise ImageError(f"{path}: the {what} must end in {', '.join(suffixes)}")
    if not path.parent.is_dir():
        raise ImageError(f"{path}: the folder {path.parent} does not exist")


def _warp_quietly(*args: Any, **kwargs: Any) -> Result:
    """Run a warp; its conflict warnings go to stderr as one line each instead of Python warnings."""
    from .core.pipeline import warp

    result = warp(*args, warn=False, **kwargs)
    for message in result.warnings:
        print(f"omniwidget: warning: {message}", file=sys.stderr)
    return result


def _cmd_warp(args: argparse.Namespace) -> None:
    from .core.errors import ImageError
    from .core.handles import load_handles
    from .core.io import check_panorama, read_image, write_image

    if args.output.resolve() == args.input.resolve():
        raise ImageError(f"{args.output}: the output would overwrite the input; choose another file")
    _check_output(args.output, (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".npy"), "output image")
    if args.map is not None:
        _check_output(args.map, (".npy",), "map file")
    if args.width is not None and (args.width < 2 or args.width % 2):
        raise ImageError(f"--width {args.width}: the width must be even and at least 2")
    handles = load_handles(args.handles)
    image = check_panorama(read_image(args.input), str(args.input))
    result = _warp_quietly(image, handles, width=args.width, order=args.order)
    if args.map is not None:
        write_image(args.map, result.inverse_map())  # .npy: the float32 array as it is
    write_image(args.output, result.image)


def _cmd_demo(args: argparse.Namespace) -> None:
    import numpy as np

    from .core.draw import draw_handles
    from .core.handles import Handles, save_handles
    from .core.io import write_image
    from .data import sample_image

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
    from .core.errors import OmniwidgetError

    args = _parser().parse_args(argv)
    try:
        {"warp": _cmd_warp, "demo": _cmd_demo}[args.command](args)
    except OmniwidgetError as exc:
        print(f"omniwidget {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"omniwidget {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0


if __name__ == "__main__":
    sys.exit(main())
