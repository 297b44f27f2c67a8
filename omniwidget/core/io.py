"""Reading and writing panoramas and files: clear errors, inputs never touched, outputs whole or absent."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .errors import ImageError

__all__ = ["SUPPORTED_DTYPES", "atomic_write_bytes", "check_panorama", "read_image", "write_image"]

#: Sample types a panorama may have; each is kept through a warp.
SUPPORTED_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)


def check_panorama(image: NDArray, name: str = "image") -> NDArray:
    """Check that ``image`` is an equirectangular panorama this toolkit can warp.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        ``W == 2 H``, ``C`` in 1..4 (gray, gray+alpha, RGB, RGBA), dtype uint8, uint16,
        float32 or float64.
    name : str
        What to call the image in messages (a file name, say).

    Returns
    -------
    ndarray
        ``image`` itself.

    Raises
    ------
    ImageError
        Naming what is wrong.
    """
    if not isinstance(image, np.ndarray):
        raise ImageError(f"{name}: expected a numpy array, got {type(image).__name__}")
    if image.ndim not in (2, 3) or (image.ndim == 3 and not 1 <= image.shape[2] <= 4):
        raise ImageError(f"{name}: expected shape (H, W) or (H, W, C) with 1 to 4 channels, got {image.shape}")
    if image.dtype.type not in SUPPORTED_DTYPES:
        raise ImageError(f"{name}: sample type {image.dtype} is not supported (use uint8, uint16, float32 or float64)")
    h, w = image.shape[:2]
    if h < 1 or w != 2 * h:
        raise ImageError(f"{name}: an equirectangular panorama is twice as wide as high, got {w} x {h}")
    return image


def read_image(path: str | os.PathLike[str]) -> NDArray:
    """Read an image file as an array in RGB(A) order, keeping its sample depth.

    Parameters
    ----------
    path : path-like
        PNG, JPEG, TIFF, WebP, ... (whatever OpenCV decodes). The file is only read.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, C)
        uint8, uint16 or float32, as stored.

    Raises
    ------
    ImageError
        If the file is missing, unreadable, empty or not a decodable image.
    """
    import cv2

    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ImageError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    if not data:
        raise ImageError(f"{path}: the file is empty")
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ImageError(f"{path}: not an image OpenCV can decode")
    if image.ndim == 3 and image.shape[2] == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    elif image.ndim == 3 and image.shape[2] == 4:
        image = cv2.cvtColor(image, cv2.COLOR_BGRA2RGBA)
    return image


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_image(path: str | os.PathLike[str], image: NDArray) -> None:
    """Write an RGB(A) or gray image whole, or not at all.

    The format follows the file's suffix. uint16 needs PNG or TIFF; float images need TIFF
    (or ``.npy``, which keeps any array exactly).

    Raises
    ------
    ImageError
        If the folder does not exist, the suffix is unknown or cannot hold the image's depth.
    """
    import cv2

    path = Path(path)
    if not path.parent.is_dir():
        raise ImageError(f"{path}: the folder {path.parent} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        import io

        buf = io.BytesIO()
        np.save(buf, image)
        atomic_write_bytes(path, buf.getvalue())
        return
    depth_ok = {
        np.uint8: (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp"),
        np.uint16: (".png", ".tif", ".tiff"),
        np.float32: (".tif", ".tiff"),
        np.float64: (".tif", ".tiff"),
    }
    allowed = depth_ok.get(image.dtype.type, ())
    if suffix not in allowed:
        raise ImageError(
            f"{path}: cannot write a {image.dtype} image as {suffix or 'a file without suffix'} (use {', '.join(allowed + ('.npy',))})"
        )
    out = image
    if out.ndim == 3 and out.shape[2] == 3:
        out = cv2.cvtColor(out, cv2.COLOR_RGB2BGR)
    elif out.ndim == 3 and out.shape[2] == 4:
        out = cv2.cvtColor(out, cv2.COLOR_RGBA2BGRA)
    ok, encoded = cv2.imencode(suffix, out)
    if not ok:
        raise ImageError(f"{path}: OpenCV could not encode the image as {suffix}")
    atomic_write_bytes(path, encoded.tobytes())
