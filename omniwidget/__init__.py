"""omniwidget: straighten and edit 360° panoramas with blended Möbius transformations.

The package is layered as the paper reads: :mod:`omniwidget.sphere` (directions, Möbius
maps), :mod:`omniwidget.document` (the handles), :mod:`omniwidget.method` (controls, the
Sec. 3.4 solve, mesh, bounded biharmonic weights), :mod:`omniwidget.raster` (the per-pixel
engine), :mod:`omniwidget.detect` (suggested lines, levelling), :mod:`omniwidget.evaluate`,
:mod:`omniwidget.io`, :mod:`omniwidget.app`, then the widget and the pane; each imports only
the layers before it. The core needs only numpy, scipy and OpenCV. Importing
:mod:`omniwidget` loads none of them: each public name is imported from its module when
first read, and each module names its heavy dependencies at its top with
:func:`omniwidget._lazy.lazy`, imported when first used (the notebook editor,
``omniwidget.Editor`` in :mod:`omniwidget.widget`, loads anywidget then).
Positions at every public boundary are ``[lon, lat]`` in degrees (conventions: :mod:`omniwidget.sphere.coords`).

Examples
--------
>>> import omniwidget as ow
>>> image = ow.sample_image()
>>> doc = ow.Handles([ow.LineHandle(start=(-60.0, 30.0), end=(-10.0, 35.0))])
>>> ow.warp(image, doc).image.shape
(512, 1024, 3)
"""

import typing as _typing

from . import _lazy
from ._version import __version__
from .errors import HandlesError, ImageError, LevelError, OmniwidgetError

if _typing.TYPE_CHECKING:  # what the public names are, for type checkers and IDEs; at run time each loads when first read
    from .app.straighten import Straightened, Structure, find_structure, straighten
    from .data import sample_image, sample_path
    from .detect.level import Level, level, level_document
    from .detect.lines import Suggestion, suggest_lines, suggestions_to_handles
    from .document.handles import CageHandle, Handles, LineHandle, Options, PointHandle, load_handles, save_handles
    from .io.images import read_image, read_panorama, to_equirectangular, write_image
    from .raster.perspective import PerspectiveView, view
    from .raster.pipeline import BlendWarning, Result, warp
    from .raster.warping import WarpResult, warp_moebius
    from .sphere.coords import lonlat_to_px, lonlat_to_xyz, px_to_lonlat, xyz_to_lonlat
    from .sphere.moebius import Moebius
    from .widget import Editor

#: Each public name and the module it is read from, on first use (``import omniwidget`` loads none of them: the
#: command line's ``--help`` and a script that needs one function do not pay for the rest).
_PUBLIC: tuple[tuple[object, tuple[str, ...]], ...] = (
    (_lazy.lazy("omniwidget.app.straighten"), ("Straightened", "Structure", "find_structure", "straighten")),
    (_lazy.lazy("omniwidget.data"), ("sample_image", "sample_path")),
    (_lazy.lazy("omniwidget.detect.level"), ("Level", "level", "level_document")),
    (_lazy.lazy("omniwidget.detect.lines"), ("Suggestion", "suggest_lines", "suggestions_to_handles")),
    (
        _lazy.lazy("omniwidget.document.handles"),
        ("CageHandle", "Handles", "LineHandle", "Options", "PointHandle", "load_handles", "save_handles"),
    ),
    (_lazy.lazy("omniwidget.io.images"), ("read_image", "read_panorama", "to_equirectangular", "write_image")),
    (_lazy.lazy("omniwidget.raster.perspective"), ("PerspectiveView", "view")),
    (_lazy.lazy("omniwidget.raster.pipeline"), ("BlendWarning", "Result", "warp")),
    (_lazy.lazy("omniwidget.raster.warping"), ("WarpResult", "warp_moebius")),
    (_lazy.lazy("omniwidget.sphere.coords"), ("lonlat_to_px", "lonlat_to_xyz", "px_to_lonlat", "xyz_to_lonlat")),
    (_lazy.lazy("omniwidget.sphere.moebius"), ("Moebius",)),
    (_lazy.lazy("omniwidget.widget"), ("Editor",)),  # the notebook editor: anywidget loads with it
)
_WHERE = {name: module for module, names in _PUBLIC for name in names}
#: The subpackages the public names come from, read as attributes (``omniwidget.raster``) before any is imported.
_SUBPACKAGES = frozenset({"app", "data", "detect", "document", "io", "method", "raster", "sphere"})


def __getattr__(name: str) -> object:
    """A public name (or subpackage) of the package, imported from its module when first read, then kept."""
    if name in _WHERE:
        value = getattr(_lazy.resolve(_WHERE[name]), name)
    elif name in _SUBPACKAGES:
        value = _lazy.resolve(_lazy.lazy(f"omniwidget.{name}"))
    else:
        raise AttributeError(f"module 'omniwidget' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


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
