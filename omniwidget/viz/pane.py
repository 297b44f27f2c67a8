"""The mesh-and-weights pane: the adaptive sphere mesh of a warp and its weights, per handle.

A thin adapter over a warp's :class:`~omniwidget.raster.pipeline.Result` for looking at Sec. 3.5 (the adaptive mesh, built
at the handles' *final* positions) and Sec. 3.2 (the bounded biharmonic weights), as in the
paper's Fig. 9. Nothing here computes anything new: the mesh, the weights and the controls'
Möbius maps all come from a :class:`~omniwidget.Result`.

* :func:`handle_weights` -- the weights per handle (a handle's controls summed);
* :func:`weights_mesh` -- the mesh as a :class:`pyvista.PolyData` with one scalar array per handle;
* :func:`render_weights` -- an off-screen render of one handle's weights on the sphere;
* :func:`weights_overlay` -- the same weights over the panorama, in 2D (numpy and OpenCV only);
* :func:`refinement_rounds` -- the mesh after each refinement round, for teaching;
* :class:`WeightsPane` -- a notebook pane that follows an :class:`~omniwidget.Editor`'s selection.

Optional dependencies
---------------------
``import omniwidget`` never imports this module, nor pyvista. Here pyvista (and VTK) load only
when a 3D function is first called; :func:`handle_weights`, :func:`weights_overlay` and
:func:`refinement_rounds` need neither. Install them with::

    pip install "pyvista>=0.49" ipywidgets        # or the "pane" extra

Off-screen rendering
--------------------
On Linux without a display (no ``DISPLAY`` or ``WAYLAND_DISPLAY``), importing this module sets
``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` unless it is already set, so VTK renders
through EGL (a GPU or Mesa's software EGL) and never tries an X server. VTK reads the variable
when it creates a render window, so it takes effect even if VTK was imported first. Set it
yourself (or to ``vtkOSOpenGLRenderWindow`` for an OSMesa build of VTK) to choose otherwise.

Notebook backend
----------------
:class:`WeightsPane` picks its backend automatically (``backend="auto"``):

* ``"html"`` when ``trame_vtk`` is importable (the ``trame-vtk`` package): the scene is
  serialised for vtk.js in this process and written as one self-contained page, the way
  pyvista's own ``export_html`` does but without starting a trame server (which would open a
  port and try to download VTK's WebAssembly build), and shown, rotatable, in an
  ``ipywidgets.HTML`` iframe;
* ``"static"`` otherwise: the off-screen render of :func:`render_weights` as a PNG in an
  ``ipywidgets.Image``.

Both need no running kernel to be built, so the pane also works in scripts and tests.
"""

from __future__ import annotations

import html as _html
import importlib.util
import io
import json
import os
import sys
import threading
import zipfile
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import check_panorama, whole_number
from .._lazy import lazy, resolve
from ..app._latest import Latest
from ..document.handles import CageHandle, Handles, LineHandle, PointHandle
from ..io.draw import display_rgb, draw_polyline
from ..method.background import BACKGROUND
from ..method.constraints import SAMPLES, Constraints
from ..method.deformation import Blend
from ..method.locate import interpolate, locate_grid
from ..method.mesh import adaptive_mesh
from ..raster.pipeline import Result
from ..sphere import coords

if TYPE_CHECKING:  # pragma: no cover
    import cv2
    import ipywidgets
    import pyvista
    from trame_vtk.modules.vtk import serializers
    from trame_vtk.tools import vtksz2html
else:
    cv2 = lazy("cv2")
    serializers = lazy("trame_vtk.modules.vtk.serializers")
    pyvista = lazy("pyvista")
    vtksz2html = lazy("trame_vtk.tools.vtksz2html")
    ipywidgets = lazy("ipywidgets")

if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

__all__ = [
    "WeightsPane",
    "final_polylines",
    "handle_label",
    "handle_weights",
    "refinement_rounds",
    "render_weights",
    "weights_mesh",
    "weights_overlay",
]

Backend = Literal["auto", "html", "static"]

#: Colour map of the weights, in pyvista and (as ``cv2.COLORMAP_VIRIDIS``) in the 2D overlay.
CMAP = "viridis"
#: Colours of the handles drawn in a render: the chosen one, and the others (RGB 0..255).
SELECTED_COLOUR = (255, 48, 48)
OTHER_COLOUR = (255, 255, 255)
#: Widest texture sent to the GPU; larger panoramas are downscaled (INTER_AREA).
MAX_TEXTURE_WIDTH = 4096
#: Points per cage edge when drawn.
EDGE_SAMPLES = SAMPLES

_INSTALL_HINT = 'the 3D pane needs pyvista: pip install "pyvista>=0.49" (with omniwidget: pip install "omniwidget[pane]")'


# --- checks --------------------------------------------------------------------------------
def _pyvista() -> Any:
    try:
        return resolve(pyvista)
    except ImportError as err:  # pragma: no cover - the tests skip without pyvista
        raise ImportError(_INSTALL_HINT) from err


def _check_result(result: object) -> Result:
    """``result`` itself, if it is a Result with a mesh and weights; else a clear error."""
    return _result_mesh(result)[0]


def _result_mesh(result: object) -> tuple[Result, Blend]:
    """``result`` and its blend (the mesh and the weights), if it is a Result with one; else a clear error."""
    if not isinstance(result, Result):
        raise TypeError(f"expected an omniwidget Result (from omniwidget.warp), got {type(result).__name__}")
    if result.blend is None:
        raise ValueError(
            "this Result has no mesh and no weights (result.weights is None): its handles all share one "
            "Möbius map (no handles, one handle, or handles that do not move each other), which is applied "
            "exactly without blending; warp two or more handles with different maps to get a mesh"
        )
    return result, result.blend


def _check_handle(result: Result, handle: object) -> int:
    if isinstance(handle, (bool, np.bool_)) or not isinstance(handle, (int, np.integer)):
        raise TypeError(f"handle must be an int (the handle's index in the document), got {type(handle).__name__}")
    n = len(result.handles)
    if not 0 <= int(handle) < n:
        raise IndexError(f"handle {int(handle)} is out of range: the document has {n} handle{'s' * (n != 1)} (0 to {n - 1})")
    return int(handle)


def handle_label(handles: Handles, handle: int) -> str:
    """The name of a handle, as in the warnings and the mesh's arrays: ``"handles[3] (line)"``.

    Parameters
    ----------
    handles : Handles
    handle : int
        Index in the document.

    Returns
    -------
    str
    """
    return f"handles[{handle}] ({handles.handles[handle].kind})"


# --- weights -------------------------------------------------------------------------------
def handle_weights(result: Result) -> NDArray[np.float64]:
    """The blend weights per handle: for each handle, the sum of its controls' columns.

    A point or a line has one control, a cage one per vertex, and a line split where it
    crosses another line one per piece (:mod:`omniwidget.method.constraints`); the weights of
    :attr:`Result.weights` are per control.

    Parameters
    ----------
    result : Result
        A warp with a mesh (``result.weights`` not None).

    Returns
    -------
    ndarray of float64, shape (n_vertices, n_handles)
        Column ``i`` is handle ``i``'s weight at each mesh vertex, in [0, 1]; rows sum to 1
        (to rounding), or with a still background (``options.anchor``) to 1 minus its
        weight, the last column of ``result.weights``. The controls are added in their
        order, so a handle with one control has exactly its column.

    Raises
    ------
    TypeError
        If ``result`` is not a :class:`~omniwidget.Result`.
    ValueError
        If the result has no weights (a single-map warp).
    """
    result, blend = _result_mesh(result)
    weights = blend.weights
    out = np.zeros((weights.shape[0], len(result.handles)), dtype=np.float64)
    for c, control in enumerate(result.controls):
        if control.handle != BACKGROUND:
            out[:, control.handle] += weights[:, c]
    return out


def final_polylines(result: Result, handle: int) -> list[NDArray[np.float64]]:
    """Where a handle is in the output: its curves mapped by its own controls' Möbius maps.

    Parameters
    ----------
    result : Result
    handle : int
        Index in the document.

    Returns
    -------
    list of ndarray of float64, each shape (s, 2)
        ``[lon, lat]`` in degrees. A point: one array of one position (its target). A line:
        one polyline per piece (a line split at a crossing has several), each the geodesic
        samples of the piece mapped by the piece's control. A cage: one closed polyline
        through the vertices' final positions (first point repeated at the end), along
        geodesic edges, as the boundary conditions have them.
    """
    handle = _check_handle(result, handle)
    h = result.handles.handles[handle]
    own = [c for c, control in enumerate(result.controls) if control.handle == handle]
    controls = result.controls
    if isinstance(h, PointHandle):
        return [controls[own[0]].moebius(np.asarray([h.position], dtype=np.float64))]
    if isinstance(h, LineHandle):
        return [controls[c].moebius(samples) for c, samples in result.constraints.lines if controls[c].handle == handle]
    if isinstance(h, CageHandle):
        finals = np.concatenate([controls[c].moebius(np.asarray([v], dtype=np.float64)) for c, v in zip(own, h.vertices, strict=True)])
        t = np.linspace(0.0, 1.0, EDGE_SAMPLES)
        edges = [coords.geodesic(a, b, t[:-1]) for a, b in zip(finals, np.roll(finals, -1, axis=0), strict=True)]
        return [np.concatenate(edges + [finals[:1]])]
    raise TypeError(f"unknown handle type {type(h).__name__}")  # pragma: no cover


def _handle_centre(result: Result, handle: int) -> NDArray[np.float64]:
    """``[lon, lat]`` of the mean direction of a handle's final polylines."""
    xyz = coords.lonlat_to_xyz(np.concatenate(final_polylines(result, handle))).mean(axis=0)
    if np.linalg.norm(xyz) < 1e-9:  # pragma: no cover - a handle spread evenly round the sphere
        xyz = coords.lonlat_to_xyz(final_polylines(result, handle)[0][0])
    return coords.xyz_to_lonlat(xyz)


# --- the mesh ------------------------------------------------------------------------------
def _vtk_faces(faces: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.column_stack([np.full(len(faces), 3, dtype=np.int64), faces]).ravel()


def weights_mesh(result: Result) -> pyvista.PolyData:
    """The adaptive sphere mesh of a warp, with the weights of every handle as point data.

    Parameters
    ----------
    result : Result
        A warp with a mesh.

    Returns
    -------
    pyvista.PolyData
        ``result.vertices`` (n, 3) and ``result.faces`` (m triangles). Point data: one float64
        array per handle, named by :func:`handle_label` (e.g. ``"handles[3] (line)"``), equal
        to ``handle_weights(result)[:, 3]``; ``"constrained"`` (uint8, 1 at the vertices
        carrying boundary conditions, ``result.constrained``); ``"lonlat"`` (float64, (n, 2),
        the vertices' ``[lon, lat]``). No array is active.

    Raises
    ------
    ValueError
        If the result has no mesh (a single-map warp).
    """
    pv = _pyvista()
    result, blend = _result_mesh(result)
    vertices = blend.vertices
    mesh = pv.PolyData(np.array(vertices, dtype=np.float64), _vtk_faces(blend.faces))
    weights = handle_weights(result)
    for i in range(weights.shape[1]):
        mesh.point_data.set_array(weights[:, i], handle_label(result.handles, i))
    constrained = np.zeros(len(vertices), dtype=np.uint8)
    constrained[blend.constrained] = 1
    mesh.point_data.set_array(constrained, "constrained")
    mesh.point_data.set_array(coords.xyz_to_lonlat(vertices), "lonlat")
    return mesh


def _textured_soup(result: Result, weights: NDArray[np.float64], image: NDArray) -> tuple[Any, Any]:
    """The mesh as separate triangles with equirectangular texture coordinates, and the texture.

    Every face gets its own three corners, with longitudes unwrapped to the face's first
    corner, so faces across the ±180° seam do not smear the whole texture (the texture
    repeats). A corner at a pole takes the mean longitude of the face's other corners.
    """
    pv = _pyvista()

    faces = np.asarray(result.faces)
    corners = np.asarray(result.vertices)[faces].reshape(-1, 3)
    lonlat = coords.xyz_to_lonlat(corners).reshape(-1, 3, 2)
    lon = coords.unwrap_lon(lonlat[..., 0], lonlat[..., :1, 0])
    pole = np.abs(lonlat[..., 1]) > 90.0 - 1e-9
    if pole.any():
        others = np.where(pole, np.nan, lon)
        lon = np.where(pole, np.nanmean(others, axis=1, keepdims=True), lon)
    width = image.shape[1]
    px = coords.lonlat_to_px(np.stack([lon, lonlat[..., 1]], axis=-1).reshape(-1, 2), width)
    tcoords = np.column_stack([(px[:, 0] + 0.5) / width, 1.0 - (px[:, 1] + 0.5) / (width // 2)])
    soup = pv.PolyData(corners, _vtk_faces(np.arange(len(corners), dtype=np.int64).reshape(-1, 3)))
    soup.active_texture_coordinates = tcoords
    soup.point_data.set_array(weights[faces.ravel()], "weight")
    rgb = display_rgb(image)
    if width > MAX_TEXTURE_WIDTH:
        # uint8 still (asarray: OpenCV's stub types any result as any MatLike)
        rgb = np.asarray(cv2.resize(rgb, (MAX_TEXTURE_WIDTH, MAX_TEXTURE_WIDTH // 2), interpolation=cv2.INTER_AREA), np.uint8)
    texture = pv.Texture(rgb)  # pyvista flips the rows: t = 1 is the top row (lat 90)
    texture.repeat = True
    texture.interpolate = True
    return soup, texture


def _add_handles(plotter: Any, result: Result, selected: int, radius: float = 1.004) -> None:
    """Draw every handle at its final position: points as spheres, lines and cages as polylines."""
    pv = _pyvista()
    for i, h in enumerate(result.handles.handles):
        colour = SELECTED_COLOUR if i == selected else OTHER_COLOUR
        width = 6 if i == selected else 3
        for curve in final_polylines(result, i):
            xyz = coords.lonlat_to_xyz(curve) * radius
            if len(xyz) == 1:
                plotter.add_mesh(pv.Sphere(radius=0.025, center=xyz[0]), color=colour, smooth_shading=True)
            else:
                plotter.add_mesh(pv.lines_from_points(xyz), color=colour, line_width=width, render_lines_as_tubes=True)
        if isinstance(h, CageHandle):
            corners = coords.lonlat_to_xyz(final_polylines(result, i)[0][: -1 : EDGE_SAMPLES - 1]) * radius
            plotter.add_mesh(pv.PolyData(corners), color=colour, point_size=3 * width, render_points_as_spheres=True)


def _plotter(
    result: Result,
    handle: int,
    *,
    window_size: tuple[int, int],
    texture: bool,
    image: NDArray | None,
    camera: str | Sequence[float],
    zoom: float,
) -> Any:
    """A populated off-screen plotter (the caller renders or exports it, then closes it)."""
    pv = _pyvista()
    result = _check_result(result)
    handle = _check_handle(result, handle)
    size = tuple(int(s) for s in window_size)
    if len(size) != 2 or min(size) < 16:
        raise ValueError(f"window_size must be (width, height) of at least 16 pixels each, got {window_size!r}")
    if not (np.isfinite(zoom) and zoom > 0):
        raise ValueError(f"zoom must be a positive number, got {zoom!r}")
    if isinstance(camera, str):
        if camera != "handle":
            raise ValueError(f"camera must be 'handle' or a [lon, lat] pair in degrees, got {camera!r}")
        look_at = _handle_centre(result, handle)
    else:
        look_at = np.asarray(camera, dtype=np.float64)
        if look_at.shape != (2,) or not np.all(np.isfinite(look_at)) or abs(look_at[1]) > 90:
            raise ValueError(f"camera must be 'handle' or a [lon, lat] pair in degrees, got {camera!r}")

    label = handle_label(result.handles, handle)
    weights = handle_weights(result)[:, handle]
    plotter = pv.Plotter(off_screen=True, window_size=size)
    plotter.set_background("#202020")
    # courier: VTK's built-in "arial" draws square brackets as parentheses
    # no title on the bar: VTK lays a long one over the labels; the text above names the handle
    bar = {"title": "", "color": "white", "n_labels": 6, "fmt": "%.1f", "font_family": "courier", "position_x": 0.1, "width": 0.8}
    if texture:
        panorama = result.image if image is None else check_panorama(image)
        soup, tex = _textured_soup(result, weights, panorama)
        plotter.add_mesh(soup, texture=tex, show_edges=True, edge_color="#00e0ff", edge_opacity=0.4, line_width=0.5, lighting=False)
    else:
        mesh = weights_mesh(result)
        plotter.add_mesh(
            mesh, scalars=label, cmap=CMAP, clim=(0.0, 1.0), show_edges=True, edge_color="black", line_width=0.5, scalar_bar_args=bar
        )
    _add_handles(plotter, result, handle)
    plotter.add_text(f"weight of {label}", position="upper_left", font_size=10, color="white", font="courier")

    centre = coords.lonlat_to_xyz(look_at)
    _, north = coords.local_frame(look_at)
    plotter.camera.focal_point = (0.0, 0.0, 0.0)
    plotter.camera.position = tuple(4.5 * centre)
    plotter.camera.up = tuple(north)
    plotter.camera.view_angle = 30.0
    plotter.camera.zoom(float(zoom))
    plotter.reset_camera_clipping_range()
    return plotter


def render_weights(
    result: Result,
    handle: int,
    *,
    window_size: tuple[int, int] = (600, 600),
    texture: bool = False,
    image: NDArray | None = None,
    camera: Literal["handle"] | Sequence[float] = "handle",
    zoom: float = 1.0,
) -> NDArray[np.uint8]:
    """An off-screen render of one handle's weights on the adaptive sphere mesh (Fig. 9).

    The mesh is drawn with its edges, coloured by the handle's weights (:func:`handle_weights`;
    viridis, fixed range [0, 1], with a colour bar), or textured with a panorama instead. Every
    handle is drawn at its final position (the mesh and the weights live on the output
    sphere): points as spheres, lines and cage edges as polylines; the chosen handle in red,
    the others in white.

    Parameters
    ----------
    result : Result
        A warp with a mesh.
    handle : int
        Index of the handle in the document.
    window_size : (int, int)
        Width and height of the image in pixels.
    texture : bool
        Texture the mesh with a panorama (equirectangular texture coordinates) instead of
        colouring it by weight.
    image : ndarray, shape (H, W[, C]), optional
        The texture (``W = 2 H``); default ``result.image``, the output, which is where the
        mesh lives. Pass the input panorama to see what the output's positions were before.
    camera : "handle" or (float, float)
        Look from outside the sphere at the handle's final position (the mean direction of its
        curves), or at this ``[lon, lat]`` in degrees; north is up.
    zoom : float
        Camera zoom; 1 shows the whole sphere.

    Returns
    -------
    ndarray of uint8, shape (height, width, 3)
        RGB.

    Raises
    ------
    ValueError
        If the result has no mesh, or an argument is out of range.
    IndexError
        If ``handle`` is not an index of the document.
    ImportError
        If pyvista is not installed.

    Notes
    -----
    Each call builds and closes its own plotter; the first call of a process also imports VTK
    and starts EGL (times in ``bench/RESULTS.md``).
    """
    plotter = _plotter(result, handle, window_size=window_size, texture=texture, image=image, camera=camera, zoom=zoom)
    try:
        shot = plotter.screenshot(return_img=True)
    finally:
        plotter.close()
    return np.ascontiguousarray(shot[..., :3], dtype=np.uint8)


#: The vtk.js viewer of an exported page adds favicon links to kitware.github.io; nothing may
#: be fetched at run time, so they point nowhere instead.
_FAVICON = "https://kitware.github.io/vtk-js/icon/favicon-${t}x${t}.png"


def _html_export(plotter: Any) -> str:
    """The plotter's scene as a standalone interactive vtk.js page (trame-vtk), fetching nothing.

    What trame's ``viewport.geometry.view.get.export`` does for a running server, done here
    directly: serialise the render window, gather its arrays, zip them as a ``.vtksz`` scene
    and write it into trame-vtk's offline viewer page.
    """
    serializers.initialize_serializers()
    context = serializers.SynchronizationContext()
    context.set_ignore_last_dependencies(True)
    window = plotter.render_window
    plotter.render()
    camera = plotter.renderer.GetActiveCamera()
    scene = serializers.serialize(None, window, serializers.reference_id(window), context, 1)
    scene["extra"] = {"vtkRefId": serializers.reference_id(window), "centerOfRotation": camera.GetFocalPoint(), "camera": serializers.reference_id(camera)}
    hashes = {e["hash"]: {**e, "content": context.get_cached_data_array(e["hash"], False)} for e in serializers.extract_array_hash(scene)}
    archive = io.BytesIO()
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("index.json", json.dumps({"hashes": hashes, "scene": scene}), compress_type=zipfile.ZIP_DEFLATED)
    page = io.StringIO()
    vtksz2html.write_html(archive.getvalue(), page)
    return page.getvalue().replace(_FAVICON, "data:,")


# --- 2D ------------------------------------------------------------------------------------
def weights_overlay(
    result: Result, handle: int, image: NDArray | None = None, width: int = 1024, *, alpha: float = 0.55, draw: bool = True
) -> NDArray[np.uint8]:
    """One handle's weights over the output panorama, in 2D (numpy and OpenCV only).

    The per-handle weights are interpolated at every pixel centre of a ``width x width/2``
    grid on the mesh (:func:`~omniwidget.method.locate.locate_grid` and
    :func:`~omniwidget.method.locate.interpolate`, as the blend does), colour-mapped (viridis,
    [0, 1]) and blended over the image.

    Parameters
    ----------
    result : Result
        A warp with a mesh.
    handle : int
        Index of the handle in the document.
    image : ndarray, shape (H, W[, C]), optional
        The panorama underneath (``W = 2 H``, resized to ``width``); default ``result.image``.
    width : int
        Output width (even).
    alpha : float
        Opacity of the colours, in [0, 1].
    draw : bool
        Draw the handles at their final positions (the chosen one red, thicker).

    Returns
    -------
    ndarray of uint8, shape (width // 2, width, 3)
        RGB.
    """
    result, blend = _result_mesh(result)
    vertices, faces = blend.vertices, blend.faces
    handle = _check_handle(result, handle)
    width = whole_number(width, "width", 2, even=True)
    if not 0.0 <= float(alpha) <= 1.0:
        raise ValueError(f"alpha must lie in [0, 1], got {alpha!r}")
    base = display_rgb(result.image if image is None else check_panorama(image))
    if base.shape[1] != width:
        shrink = base.shape[1] > width
        # uint8 still (asarray: OpenCV's stub types any result as any MatLike)
        base = np.asarray(cv2.resize(base, (width, width // 2), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR), np.uint8)
    face, bary = locate_grid(vertices, faces, width)
    w = interpolate(handle_weights(result)[:, handle], faces, face, bary)
    levels = np.clip(np.rint(np.asarray(w, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)
    colours = cv2.applyColorMap(levels, cv2.COLORMAP_VIRIDIS)[..., ::-1]
    out = np.asarray(cv2.addWeighted(colours, float(alpha), base, 1.0 - float(alpha), 0.0), np.uint8)  # uint8, as above
    if draw:
        thin = max(1, width // 1024)
        for i in range(len(result.handles)):
            colour = SELECTED_COLOUR if i == handle else OTHER_COLOUR
            for curve in final_polylines(result, i):
                if len(curve) == 1:
                    x, y = coords.lonlat_to_px(curve[0], width)
                    cv2.circle(out, (round(x), round(y)), 4 * thin + 2 * (i == handle), colour, -1, cv2.LINE_AA)
                else:
                    draw_polyline(out, curve, colour, thin * (2 if i == handle else 1))
    return out


# --- refinement ----------------------------------------------------------------------------
def refinement_rounds(source: Result | object) -> list[tuple[NDArray[np.float64], NDArray[np.int64]]]:
    """The adaptive mesh after each refinement round of Sec. 3.5, for teaching.

    Parameters
    ----------
    source : Result or Constraints
        A warp with a mesh, or the constraints of one
        (:func:`~omniwidget.method.constraints.build_constraints`); the mesh is rebuilt from
        their points with :func:`~omniwidget.method.mesh.adaptive_mesh`'s defaults, as
        :func:`~omniwidget.warp` does.

    Returns
    -------
    list of (vertices, faces)
        ``vertices`` float64 (n_r, 3), ``faces`` int64 (m_r, 3): the base icosphere, the mesh
        after each round (their faces are the 1-to-4 splits as they are, with T-junctions:
        for plotting), and last the final mesh with the samples added (for a Result, its own
        ``vertices`` and ``faces``). Vertex counts increase from entry to entry.
    """
    own: tuple[NDArray[np.float64], NDArray[np.int64]] | None = None
    if isinstance(source, Result):
        checked, blend = _result_mesh(source)
        constraints, own = checked.constraints, (blend.vertices, blend.faces)
    elif isinstance(source, Constraints):
        constraints = source
    else:
        raise TypeError(f"expected a Result or Constraints, got {type(source).__name__}")
    mesh = adaptive_mesh(constraints.points)
    final = own if own is not None else (mesh.vertices, mesh.faces)
    return [*mesh.rounds, final]


# --- the notebook pane ---------------------------------------------------------------------
def _choose_backend(backend: str) -> str:
    if backend not in ("auto", "html", "static"):
        raise ValueError(f"backend must be 'auto', 'html' or 'static', got {backend!r}")
    has_trame = importlib.util.find_spec("trame_vtk") is not None
    if backend == "html" and not has_trame:
        raise ImportError('backend="html" needs trame-vtk: pip install trame-vtk (or use backend="auto")')
    if backend == "auto":
        return "html" if has_trame else "static"
    return backend


def _png(rgb: NDArray[np.uint8]) -> bytes:
    ok, data = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:  # pragma: no cover
        raise RuntimeError("could not encode the render as PNG")
    return data.tobytes()


class WeightsPane:
    """A notebook pane showing one handle's weights on the sphere, following an editor's selection.

    Parameters
    ----------
    source : Editor or Result
        An :class:`~omniwidget.Editor`: the pane shows its preview result
        (:attr:`~omniwidget.Editor.preview_result`), recolours when ``editor.selected``
        changes and redraws when a new preview arrives. Or a :class:`~omniwidget.Result`,
        shown as it is (change :attr:`handle` to recolour).
    handle : int, optional
        The handle to show first; default the editor's selection, or 0.
    backend : {"auto", "html", "static"}
        ``"auto"``: ``"html"`` (interactive, a vtk.js page written with trame-vtk) when ``trame_vtk``
        is importable, else ``"static"`` (a PNG of :func:`render_weights`).
    window_size : (int, int)
        Size of the render.
    texture : bool
        Texture the mesh with the output panorama instead of colouring it.
    zoom : float
        As in :func:`render_weights`.

    Attributes
    ----------
    widget : ipywidgets.VBox
        What the notebook shows: a caption and the view (``ipywidgets.Image`` or ``ipywidgets.HTML``).
    backend : str
        ``"html"`` or ``"static"``, as chosen.
    image : ndarray of uint8, shape (height, width, 3) or None
        The last static render (None with the html backend, or before there is a mesh).
    html : str or None
        The last exported page (html backend).
    message : str
        Why nothing is shown, or ``""``.

    Notes
    -----
    Deselecting (``editor.selected == -1``) keeps the last handle on show. A result without a
    mesh (a single Möbius map) or a selection the preview does not have yet shows a message
    instead of raising. Call :meth:`close` to stop following the editor.

    Following an editor, the pane redraws on a thread of its own (only the newest redraw
    runs), so the editor's next preview never waits for it; :meth:`wait` blocks until the
    pane shows the editor's current selection and preview. The first draw, and assigning
    :attr:`handle`, draw at once.
    """

    def __init__(
        self,
        source: Any,
        handle: int | None = None,
        *,
        backend: Backend = "auto",
        window_size: tuple[int, int] = (480, 480),
        texture: bool = False,
        zoom: float = 1.0,
    ) -> None:
        self.backend = _choose_backend(backend)
        self._window_size = window_size
        self._texture = bool(texture)
        self._zoom = zoom
        self._lock = threading.RLock()
        self._worker = Latest("omniwidget-pane")
        self.image: NDArray[np.uint8] | None = None
        self.html: str | None = None
        self.message = ""
        self._shown: Result | None = None
        if isinstance(source, Result):
            self._editor = None
            self._result: Result | None = source
        elif hasattr(source, "selected") and hasattr(source, "observe") and hasattr(source, "preview_result"):
            self._editor = source
            self._result = None
        else:
            raise TypeError(f"expected an omniwidget Editor or Result, got {type(source).__name__}")
        if handle is None:
            handle = self._editor.selected if self._editor is not None and self._editor.selected >= 0 else 0
        self._handle = int(handle)
        self._caption = ipywidgets.HTML()
        if self.backend == "static":
            self._view: Any = ipywidgets.Image(format="png", layout=ipywidgets.Layout(width=f"{int(window_size[0])}px"))
        else:
            self._view = ipywidgets.HTML()
        self.widget = ipywidgets.VBox([self._caption, self._view])
        self.widget.add_class("ow-weights-pane")
        if self._editor is not None:
            if self._editor.preview_result is None:
                self._editor.wait()
            self._editor.observe(self._on_selected, names="selected")
            # "status" is the editor's last trait set when a preview arrives, after preview_result
            self._editor.observe(self._on_status, names="status")
        self.refresh()

    # --- following the editor ----------------------------------------------------------------
    @property
    def result(self) -> Result | None:
        """The result on show: the editor's current preview, or the Result given."""
        return self._editor.preview_result if self._editor is not None else self._result

    @property
    def handle(self) -> int:
        """Index of the handle on show; assigning one redraws."""
        return self._handle

    @handle.setter
    def handle(self, value: int) -> None:
        result = self.result
        if result is not None:
            _check_handle(result, value)
        self._handle = int(value)
        self.refresh()

    def _on_selected(self, change: dict) -> None:
        if change["new"] is not None and change["new"] >= 0:
            self._handle = int(change["new"])
            self._worker.submit(self._redraw)

    def _on_status(self, change: dict) -> None:
        if self.result is not self._shown:  # a new preview (not merely "busy")
            self._worker.submit(self._redraw)

    def _redraw(self) -> None:
        """:meth:`refresh` on the pane's thread: a failure is shown in the caption, never lost in the thread."""
        try:
            self.refresh()
        except Exception as exc:  # noqa: BLE001 - shown in the pane
            self._show_message(f"could not draw the weights: {type(exc).__name__}: {exc}")

    def wait(self, timeout: float | None = 60.0) -> bool:
        """Block until the redraws asked for so far are done.

        Parameters
        ----------
        timeout : float or None
            Seconds; None waits for ever.

        Returns
        -------
        bool
            False if the timeout passed first.
        """
        return self._worker.wait(timeout)

    def close(self) -> None:
        """Stop following the editor and close the widgets."""
        if self._editor is not None:
            self._editor.unobserve(self._on_selected, names="selected")
            self._editor.unobserve(self._on_status, names="status")
        self.widget.close()

    # --- drawing -------------------------------------------------------------------------------
    def _show_message(self, message: str) -> None:
        self.message = message
        self._caption.value = f"<b>weights</b>: {_html.escape(message)}"

    def refresh(self) -> None:
        """Redraw the current handle of the current result (called by the observers)."""
        with self._lock:
            result = self._shown = self.result
            if result is None:
                self._show_message("no result yet")
                return
            blend = result.blend
            if blend is None:
                self._show_message("this result has no mesh: its handles share one Möbius map (result.weights is None)")
                return
            if not 0 <= self._handle < len(result.handles):
                self._show_message(f"handle {self._handle} is not in the result on show yet ({len(result.handles)} handles)")
                return
            self.message = ""
            label = handle_label(result.handles, self._handle)
            kwargs: dict[str, Any] = {"window_size": self._window_size, "texture": self._texture, "zoom": self._zoom, "camera": "handle", "image": None}
            if self.backend == "static":
                self.image = render_weights(result, self._handle, **kwargs)
                self._view.value = _png(self.image)
            else:
                plotter = _plotter(result, self._handle, **kwargs)
                try:
                    self.html = _html_export(plotter)
                finally:
                    plotter.close()
                w, h = (int(s) for s in self._window_size)
                self._view.value = (
                    f'<iframe class="ow-weights-view" data-handle="{self._handle}" srcdoc="{_html.escape(self.html)}" '
                    f'width="{w}" height="{h}" style="border:0"></iframe>'
                )
            self._caption.value = f"<b>weights of {_html.escape(label)}</b> on the adaptive mesh ({len(blend.vertices)} vertices)"

    def _repr_mimebundle_(self, **kwargs: Any) -> Any:
        return self.widget._repr_mimebundle_(**kwargs)
