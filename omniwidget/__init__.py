"""omniwidget: straighten and edit 360° panoramas with blended Möbius transformations.

The numerical core lives in :mod:`omniwidget.core` and needs only numpy, scipy and
OpenCV; importing :mod:`omniwidget` loads nothing more (the notebook editor,
``omniwidget.Editor`` in :mod:`omniwidget.widget`, loads anywidget when first used).
Positions at every public boundary are ``[lon, lat]`` in degrees (conventions: :mod:`omniwidget.core.coords`).

Examples
--------
>>> import omniwidget as ow
>>> image = ow.sample_image()
>>> doc = ow.Handles([ow.LineHandle(start=(-60.0, 30.0), end=(-10.0, 35.0))])
>>> ow.warp(image, doc).image.shape
(512, 1024, 3)
"""

from ._version import __version__
from .core import (
    BlendWarning,
    CageHandle,
    Handles,
    HandlesError,
    ImageError,
    LineHandle,
    Moebius,
    OmniwidgetError,
    Options,
    PointHandle,
    Result,
    WarpResult,
    load_handles,
    read_image,
    read_panorama,
    save_handles,
    to_equirectangular,
    warp,
    warp_moebius,
    write_image,
)
from .data import sample_image, sample_path


def __getattr__(name: str):  # noqa: ANN202 - the widgets load their stack only when asked for
    if name == "Editor":
        from .widget import Editor

        return Editor
    raise AttributeError(f"module 'omniwidget' has no attribute {name!r}")


__all__ = [
    "BlendWarning",
    "CageHandle",
    "Editor",
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
    "__version__",
    "load_handles",
    "read_image",
    "read_panorama",
    "sample_image",
    "sample_path",
    "save_handles",
    "to_equirectangular",
    "warp",
    "warp_moebius",
    "write_image",
]
