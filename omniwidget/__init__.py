"""omniwidget: straighten and edit 360° panoramas with blended Möbius transformations.

The package is layered as the paper reads: :mod:`omniwidget.sphere` (directions, Möbius
maps), :mod:`omniwidget.document` (the handles), :mod:`omniwidget.method` (controls, the
Sec. 3.4 solve, mesh, bounded biharmonic weights), :mod:`omniwidget.raster` (the per-pixel
engine), :mod:`omniwidget.detect` (suggested lines, levelling), :mod:`omniwidget.evaluate`,
:mod:`omniwidget.io`, :mod:`omniwidget.app`, then the widget and the pane; each imports only
the layers before it. The core needs only numpy,
scipy and OpenCV; importing :mod:`omniwidget` loads nothing more (the notebook editor,
``omniwidget.Editor`` in :mod:`omniwidget.widget`, loads anywidget when first used).
Positions at every public boundary are ``[lon, lat]`` in degrees (conventions: :mod:`omniwidget.sphere.coords`).

Examples
--------
>>> import omniwidget as ow
>>> image = ow.sample_image()
>>> doc = ow.Handles([ow.LineHandle(start=(-60.0, 30.0), end=(-10.0, 35.0))])
>>> ow.warp(image, doc).image.shape
(512, 1024, 3)
"""

from ._version import __version__
from .app.straighten import Straightened, Structure, find_structure, straighten
from .data import sample_image, sample_path
from .detect.level import Level, level, level_document
from .detect.lines import Suggestion, suggest_lines, suggestions_to_handles
from .document.handles import CageHandle, Handles, LineHandle, Options, PointHandle, load_handles, save_handles
from .errors import HandlesError, ImageError, LevelError, OmniwidgetError
from .io.images import read_image, read_panorama, to_equirectangular, write_image
from .raster.perspective import PerspectiveView, view
from .raster.pipeline import BlendWarning, Result, warp
from .raster.warping import WarpResult, warp_moebius
from .sphere.coords import lonlat_to_px, lonlat_to_xyz, px_to_lonlat, xyz_to_lonlat
from .sphere.moebius import Moebius


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
    "Level",
    "LevelError",
    "LineHandle",
    "Moebius",
    "OmniwidgetError",
    "Options",
    "PerspectiveView",
    "PointHandle",
    "Result",
    "Straightened",
    "Structure",
    "Suggestion",
    "WarpResult",
    "__version__",
    "load_handles",
    "level",
    "level_document",
    "find_structure",
    "lonlat_to_px",
    "lonlat_to_xyz",
    "px_to_lonlat",
    "read_image",
    "read_panorama",
    "sample_image",
    "sample_path",
    "save_handles",
    "straighten",
    "suggest_lines",
    "suggestions_to_handles",
    "to_equirectangular",
    "view",
    "warp",
    "warp_moebius",
    "write_image",
    "xyz_to_lonlat",
]
