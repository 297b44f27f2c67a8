"""Level a panorama: the camera's pitch and roll from the vertical edges it sees.

Every vertical 3D edge is seen along a great circle through the vertical direction: the
plane through the camera and the edge contains the vertical. So the great circles of the
vertical edges all pass through one point of the sphere, the vertical vanishing direction
``v``, and their unit normals ``n_i`` satisfy ``n_i · v = 0``. :func:`level` finds ``v``
among the suggested lines (:func:`omniwidget.detect.lines.suggest_lines`) robustly: a
RANSAC over pairs of arcs whose crossing lies near the zenith, then a reweighted least
squares refit on the inliers (``v`` the smallest eigenvector of ``Σ w_i n_i n_iᵀ``, Huber
weights). The rotation that takes ``v`` to the zenith by the shortest turn levels the
panorama without turning it about the vertical.

Convention
----------
The camera's tilt is ``T = R_y(pitch) R_x(roll)``: ``R_x(a)`` turns by ``a`` degrees
right-handedly about the forward axis ``+x`` (lon 0, lat 0), ``R_y(a)`` about ``+y``
(lon 90, lat 0). A direction ``d`` of the level world is seen in the tilted panorama at
``T d``; in particular the zenith is seen at ``up = T (0, 0, 1) = (sin p cos r, -sin r,
cos p cos r)``, so a positive pitch moves the zenith towards lon 0 and a positive roll
towards lon -90. :func:`omniwidget.evaluate.scenes.synthetic_room` renders with the same
convention.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..document.handles import Handle, Handles, Options, PointHandle
from ..method.kinds import kind_of
from ..sphere import coords
from ..sphere.moebius import Moebius
from . import vertical
from .lines import DETECT_WIDTH, Suggestion, check_detectable, suggest_lines

__all__ = ["LEVEL_ID", "Level", "level", "level_document", "tilt_rotation", "up_to_pitch_roll"]

LonLat = tuple[float, float]
FloatArray = NDArray[np.float64]

#: The id of a point handle that levels its document by itself (:func:`level_document` takes it as the document's levelling and replaces it by ``options.up``).
LEVEL_ID = "level"
#: Farthest the vertical direction is looked for from the zenith, degrees (:data:`omniwidget.detect.vertical.MAX_TILT`).
MAX_TILT = vertical.MAX_TILT


def tilt_rotation(pitch: float, roll: float) -> FloatArray:
    """The camera tilt ``T = R_y(pitch) R_x(roll)`` of the module's convention, shape (3, 3).

    Parameters
    ----------
    pitch, roll : float
        Degrees.

    Returns
    -------
    ndarray of float64, shape (3, 3)
        A level direction ``d`` is seen at ``T @ d`` in the tilted panorama.
    """
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    cr, sr = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return about_y @ about_x


def up_to_pitch_roll(up: ArrayLike) -> tuple[float, float]:
    """Pitch and roll (degrees) of a camera that sees the zenith at ``up`` (a ``[lon, lat]``).

    The inverse of ``up = T (0, 0, 1) = (sin p cos r, -sin r, cos p cos r)``, with
    ``roll`` in ``[-90, 90]``.
    """
    u = coords.lonlat_to_xyz(up)
    roll = -math.degrees(math.asin(float(np.clip(u[1], -1.0, 1.0))))
    pitch = math.degrees(math.atan2(float(u[0]), float(u[2])))
    return pitch, roll


@dataclass(frozen=True)
class Level:
    """How far a panorama's camera was from level, and the rotation that levels it.

    Attributes
    ----------
    pitch, roll : float
        Degrees, in the module's convention (``up = (sin p cos r, -sin r, cos p cos r)``).
    up : (float, float)
        ``[lon, lat]`` in degrees where the input panorama sees the true vertical.
    edges : tuple of Suggestion
        The vertical edges the estimate rests on (the inliers).
    residual : float
        Root mean square distance in degrees of the inliers' great circles from ``up``.
    """

    pitch: float
    roll: float
    up: LonLat
    edges: tuple[Suggestion, ...] = ()
    residual: float = 0.0

    @property
    def tilt(self) -> float:
        """Angle of ``up`` from the zenith, degrees: how far the camera was from level."""
        return float(90.0 - self.up[1])

    def rotation(self) -> FloatArray:
        """The levelling rotation as a matrix, shape (3, 3): ``up`` to the zenith about ``up × z``."""
        return self.moebius().apply_xyz(np.eye(3)).T

    def moebius(self) -> Moebius:
        """The levelling rotation as a Möbius map, input to output: ``up`` to the zenith, the yaw unchanged."""
        return Moebius.levelling(self.up)

    def handles(self) -> Handles:
        """A handles document whose warp is exactly the levelling rotation: no handles, ``options.up`` set."""
        return Handles((), Options(up=self.up))

    def pose(self) -> dict[str, float]:
        """The tilt as the Photo Sphere XMP's pose angles: ``{"PosePitchDegrees": pitch, "PoseRollDegrees": roll}``.

        GPano's pitch and roll as Pannellum reads them (``horizonPitch``, ``horizonRoll``):
        it shows the level direction ``d`` where the panorama has ``R_y(pitch) R_x(roll) d``
        in the axes (forward, 90° to the right, up), which is :func:`tilt_rotation` in
        :mod:`omniwidget.sphere.coords`' axes; so they are :attr:`pitch` and :attr:`roll` as
        they are. A viewer undoes that turn, which differs from :meth:`moebius` (the shortest
        turn, the yaw kept) by a turn about the vertical of about ``pitch * roll / 2``
        radians. The heading is not found by levelling (nothing sees the compass): left out.
        ``omniwidget level --pose-only`` writes these into the file.
        """
        return {"PosePitchDegrees": float(self.pitch), "PoseRollDegrees": float(self.roll)}


def level_document(doc: Handles, up: Level | LonLat | Moebius) -> Handles:
    """The editor's one-click Level: ``doc`` with its input levelled (``options.up``), the result changed only by the turn.

    The document's ``options.up`` becomes the new ``up``: the method then works on the input
    turned by ``L_new`` (``up`` to the zenith, :meth:`Options.levelling`), and the still
    background, if on, stays on and shows the levelled panorama. Each handle's output is
    carried by ``Q = L_new L_old⁻¹`` (``L_old`` the document's levelling before, the
    identity without one): a point's target becomes ``Q(target)`` and its turn changes by
    ``Q``'s local turns (its map becomes ``Q M Q⁻¹`` in the levelled frame), a cage's
    targets ``Q(targets)``, a line's explicit targets ``Q(targets)``. A rectified line
    without targets stays rectified: it is straightened again in the new frame, where its
    verticals are vertical. So near points, cages and fixed lines, and far from every
    handle, the new warp is ``Q`` after the old one; only rectified lines change beyond
    that. A point handle with id ``"level"`` (:data:`LEVEL_ID`, a levelling held as a
    handle) is taken as the old levelling and removed.

    Parameters
    ----------
    doc : Handles
    up : Level, (float, float) or Moebius
        Where the input sees the true vertical (a :class:`Level`, or its ``up``), or the
        levelling turn itself (:meth:`Level.moebius`: a rotation taking some ``up`` to the
        zenith by the shortest turn).

    Returns
    -------
    Handles
        A new document; ``doc`` is not changed.

    Raises
    ------
    ValueError
        For a rotation that also turns about the vertical (a levelling keeps the yaw), or
        an ``up`` farther than 45° from the zenith.
    """
    new_up = _up_of(up)
    legacy = [h for h in doc.handles if h.id == LEVEL_ID and isinstance(h, PointHandle)]
    old = doc.options.levelling() or Moebius.identity()
    if legacy:
        old = legacy[0].moebius() @ old
    new = Moebius.levelling(new_up)
    q = new @ old.inverse
    out: list[Handle] = [kind_of(h).carried(h, old, q) for h in doc.handles if all(h is not gone for gone in legacy)]
    return Handles(tuple(out), replace(doc.options, up=new_up))


def _up_of(up: Level | LonLat | Moebius) -> LonLat:
    """``up`` as ``[lon, lat]``: a Level's, a pair's, or the direction a levelling turn takes to the zenith."""
    if isinstance(up, Level):
        return up.up
    if isinstance(up, Moebius):
        lon, lat = up.inverse(np.array([0.0, 90.0]))
        found = (float(lon), float(lat))
        if lat <= 0 or not Moebius.levelling(found).isclose(up, 1e-7):
            raise ValueError("the rotation is not a levelling: it also turns about the vertical (a levelling keeps the yaw)")
        return found
    lon, lat = (float(v) for v in up)
    return (lon, lat)


def level(
    image: NDArray,
    *,
    suggestions: Sequence[Suggestion] | None = None,
    min_edges: int = 4,
    max_tilt: float = MAX_TILT,
) -> Level:
    """Estimate how far the camera was from level, from the vertical edges of the panorama.

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        Equirectangular panorama (as for :func:`omniwidget.detect.lines.suggest_lines`).
    suggestions : sequence of Suggestion, optional
        The lines to look among; by default every line :func:`suggest_lines` finds.
    min_edges : int
        Fewest distinct vertical edges to trust, ``>= 2``.
    max_tilt : float
        Farthest from the zenith the vertical is looked for, degrees, in ``(0, 90)``.

    Returns
    -------
    Level

    Raises
    ------
    LevelError
        If fewer than ``min_edges`` vertical edges are found, if they do not fix the
        vertical (all in one plane), or if they disagree on it.
    ImageError
        If ``image`` is not a usable panorama.
    """
    if isinstance(min_edges, bool) or not isinstance(min_edges, int | np.integer) or min_edges < 2:
        raise ValueError(f"min_edges must be an integer of at least 2, got {min_edges!r}")
    if isinstance(max_tilt, bool) or not isinstance(max_tilt, int | float | np.integer | np.floating) or not 0 < max_tilt < 90:
        raise ValueError(f"max_tilt must be a number of degrees in (0, 90), got {max_tilt!r}")
    if suggestions is None:
        suggestions = suggest_lines(image, max_lines=None, structure=False)  # every vertical, texture too
    else:
        check_detectable(image)  # the same checks of the image (not its grey copy: the suggestions are found)
    width = min(int(image.shape[1]), DETECT_WIDTH)  # the width the lines were found at
    v, inliers, residual = vertical.find_up(suggestions, width, min_edges=min_edges, max_tilt=max_tilt)
    lon, lat = coords.xyz_to_lonlat(v)
    up = (float(lon), float(lat))
    pitch, roll = up_to_pitch_roll(up)
    return Level(pitch=pitch, roll=roll, up=up, edges=tuple(s for s, ok in zip(suggestions, inliers, strict=True) if ok), residual=residual)
