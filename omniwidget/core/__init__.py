"""The numerical core: numpy, scipy and OpenCV only; never imports a widget or plotting package."""

from .coords import lonlat_to_px, lonlat_to_xyz, px_to_lonlat, xyz_to_lonlat
from .errors import HandlesError, ImageError, OmniwidgetError
from .handles import CageHandle, Handles, LineHandle, Options, PointHandle, load_handles, save_handles
from .io import read_image, read_panorama, to_equirectangular, write_image
from .moebius import Moebius
from .pipeline import BlendWarning, Result, warp
from .warping import WarpResult, warp_moebius

__all__ = [
    "BlendWarning",
    "CageHandle",
    "Handles",
    "HandlesError",
    "ImageError",
    "LineHandle",
    "Moebius",
    "OmniwidgetError",
    "Options",
    "PointHandle",
    "Result",
    "WarpResult",
    "load_handles",
    "lonlat_to_px",
    "lonlat_to_xyz",
    "px_to_lonlat",
    "read_image",
    "read_panorama",
    "save_handles",
    "to_equirectangular",
    "warp",
    "warp_moebius",
    "write_image",
    "xyz_to_lonlat",
]
