"""Validation shared by every layer: whole numbers, images, input files."""

from __future__ import annotations

import math
import operator
import os
import stat
from typing import SupportsIndex

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ImageError, NotRegularFileError, OmniwidgetError

__all__ = ["SUPPORTED_DTYPES", "check_image", "check_inverse_map", "check_panorama", "limit", "require_regular_file", "whole_number"]

#: Sample types a panorama may have; each is kept through a warp.
SUPPORTED_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)
_ROWS_PER_CHECK = 256  # rows of a float image checked for NaN at a time (bounded memory)

#: What :func:`require_regular_file` calls each kind of file that is not a regular one.
_SPECIAL_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a folder"),
)


def limit(name: str, default: int) -> int:
    """A cap of the toolkit: ``default``, or the environment variable ``OMNIWIDGET_MAX_<NAME>`` when it is set.

    Parameters
    ----------
    name : str
        The cap's name in upper case, e.g. ``"HANDLES"`` (``OMNIWIDGET_MAX_HANDLES``).
    default : int
        The documented cap.

    Returns
    -------
    int

    Raises
    ------
    OmniwidgetError
        If the variable is set to anything but a positive whole number (``1e6`` is taken).
    """
    variable = f"OMNIWIDGET_MAX_{name}"
    given = os.environ.get(variable, "").strip()
    if not given:
        return default
    try:
        value = float(given)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 1 and value == int(value)):
        raise OmniwidgetError(f"{variable}={given!r}: expected a positive whole number")
    return int(value)


def require_regular_file(path: str | os.PathLike[str], what: str) -> None:
    """Refuse to read ``path`` when it exists but is not a regular file (a FIFO, a device, a socket, a folder).

    Reading a FIFO waits for a writer that may never come, and a device such as
    ``/dev/zero`` never ends: either would hang or exhaust the machine. The check looks
    at the file's kind only (``os.stat``, which follows symbolic links and neither opens
    nor blocks); a missing or unreadable path passes, and the read that follows says so in
    its own words.

    Parameters
    ----------
    path : path-like
        The file about to be opened for reading.
    what : str
        What the file is, for the message: ``"handles file"``, ``"image"``, ``"map"``.

    Raises
    ------
    NotRegularFileError
        A :class:`~omniwidget.errors.OmniwidgetError` (so a ``ValueError``), one line:
        ``"<path>: cannot read the <what>: it is a FIFO (named pipe), not a regular file"``.

    Examples
    --------
    >>> require_regular_file("/dev/null", "handles file")
    Traceback (most recent call last):
    ...
    omniwidget.errors.NotRegularFileError: /dev/null: cannot read the handles file: it is a character device, not a regular file
    """
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):  # missing, unreadable, a name with a NUL byte: the read says it
        return
    if stat.S_ISREG(mode):
        return
    kind = next((name for test, name in _SPECIAL_KINDS if test(mode)), "a special file")
    raise NotRegularFileError(os.fspath(path), what, kind)


def whole_number(value: object, name: str, minimum: int = 0, *, even: bool = False) -> int:
    """``value`` as an ``int`` if it is a whole number (not a bool) of at least ``minimum``, else ValueError.

    Parameters
    ----------
    value : object
        Anything; numpy integers are accepted, floats and bools are not.
    name : str
        How the message names it, e.g. ``"samples"``.
    minimum : int
    even : bool
        Also require an even number.

    Returns
    -------
    int
    """
    kind = {0: "a non-negative integer", 1: "a positive integer"}.get(minimum, f"an integer of at least {minimum}")
    if even:
        kind = f"an even integer of at least {minimum}"
    if isinstance(value, bool) or not isinstance(value, SupportsIndex):
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    try:
        out = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be {kind}, got {value!r}") from None
    if out < minimum or (even and out % 2):
        raise ValueError(f"{name} must be {kind}, got {out}")
    return out


def check_image(image: NDArray, name: str) -> tuple[int, int]:
    """Shape, channels and dtype of an image (any aspect ratio); returns ``(H, W)``."""
    if not isinstance(image, np.ndarray):
        raise ImageError(f"{name}: expected a numpy array, got {type(image).__name__}")
    if image.ndim not in (2, 3) or (image.ndim == 3 and not 1 <= image.shape[2] <= 4):
        raise ImageError(f"{name}: expected shape (H, W) or (H, W, C) with 1 to 4 channels, got {image.shape}")
    if image.dtype.type not in SUPPORTED_DTYPES:
        raise ImageError(f"{name}: sample type {image.dtype} is not supported (use uint8, uint16, float32 or float64)")
    if not image.dtype.isnative:
        raise ImageError(
            f"{name}: the samples are in non-native byte order ({image.dtype.str}); use image.astype(image.dtype.newbyteorder('='))"
        )
    h, w = image.shape[:2]
    if h < 1 or w < 1:
        raise ImageError(f"{name}: the image is empty ({w} x {h})")
    if image.dtype.kind == "f":
        for start in range(0, h, _ROWS_PER_CHECK):
            block = image[start : start + _ROWS_PER_CHECK]
            bad = ~np.isfinite(block)
            if bad.any():
                count = sum(int(np.count_nonzero(~np.isfinite(image[s : s + _ROWS_PER_CHECK]))) for s in range(start, h, _ROWS_PER_CHECK))
                row, col = np.argwhere(bad)[0][:2]
                raise ImageError(
                    f"{name}: {count} sample(s) are not finite (NaN or infinity), the first at row {start + row}, column {col}; "
                    "replace them (numpy.nan_to_num, say) before warping"
                )
    return h, w


def check_panorama(image: NDArray, name: str = "image") -> NDArray:
    """Check that ``image`` is an equirectangular panorama this toolkit can warp.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        ``W == 2 H`` (any size from 2 x 1), ``C`` in 1..4 (gray, gray+alpha, RGB, RGBA),
        dtype uint8, uint16, float32 or float64 in native byte order; a float image must be
        finite (no NaN or infinity).
    name : str
        What to call the image in messages (a file name, say).

    Returns
    -------
    ndarray
        ``image`` itself.

    Raises
    ------
    ImageError
        Naming what is wrong; an image that is not 2:1 is told how to become one
        (:func:`omniwidget.to_equirectangular`, ``omniwidget warp --fit``).
    """
    h, w = check_image(image, name)
    if w != 2 * h:
        if w > 2 * h and w % 2 == 0:
            how = (
                'if it covers 360° of longitude but was cropped at the top and bottom, pad it with fit="pad" (rows added above '
                'and below), or resize it with fit="stretch"'
            )
        else:
            how = 'resize it with fit="stretch"'
        raise ImageError(
            f"{name}: an equirectangular panorama is twice as wide as high, got {w} x {h}; "
            f"{how} (omniwidget warp --fit, or omniwidget.to_equirectangular)"
        )
    return image


def check_inverse_map(inverse_map: ArrayLike, dtype: type[np.floating] = np.float64) -> NDArray[np.floating]:
    """``inverse_map`` as an array of ``dtype`` if it is an inverse map, else ValueError saying what is wrong.

    Parameters
    ----------
    inverse_map : array_like, shape (H, 2H, 2)
        For each output pixel, the input ``[lon, lat]`` in degrees; finite, ``H >= 3``.
    dtype : numpy floating type

    Returns
    -------
    ndarray of dtype, shape (H, 2H, 2)
    """
    m = np.asarray(inverse_map, dtype=dtype)
    if m.ndim != 3 or m.shape[2] != 2 or m.shape[1] != 2 * m.shape[0] or m.shape[0] < 3:
        raise ValueError(f"expected an inverse map of shape (H, 2H, 2) with H >= 3, got {m.shape}")
    if not np.all(np.isfinite(m)):
        bad = np.argwhere(~np.isfinite(m).all(axis=-1))[0]
        raise ValueError(f"the inverse map has NaN or infinite entries (first at row {bad[0]}, column {bad[1]})")
    return m
