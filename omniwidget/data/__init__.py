"""The bundled sample panorama.

``hotel_room.jpg``: 1024 x 512, CC0, Greg Zaal (HDRI Haven), tone-mapped from Debian's
blender-data ``studiolights/world/interior.exr``.
"""

from __future__ import annotations

from pathlib import Path

from numpy.typing import NDArray

from ..io.images import read_image

__all__ = ["sample_image", "sample_path"]

_HERE = Path(__file__).parent


def sample_path() -> Path:
    """Path of the bundled CC0 panorama ``hotel_room.jpg`` (1024 x 512)."""
    return _HERE / "hotel_room.jpg"


def sample_image() -> NDArray:
    """The bundled panorama as an RGB uint8 array, shape (512, 1024, 3)."""
    return read_image(sample_path())
