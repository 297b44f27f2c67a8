"""A point handle's reach: with the still background, its turn and zoom cover a region.

Bounded biharmonic weights and the background's ease fall within a few degrees of a point
handle, so without this a zoom or a turn shows on a spot of about a degree. With
``options.anchor`` set, each point handle that turns or zooms gets a *ladder* of Möbius maps
from its pure shift (rung 0, :meth:`Moebius.point_map` with unit scale and no turn) to its
own map (rung ``n``), each rung a partial turn and zoom about the same centre
(:func:`rung_maps`). Mesh vertices within a third of the reach ``R`` of the target carry
the handle's own map; from ``R / 3`` to ``R`` they step down the ladder by
:func:`profiles`, and beyond ``R`` no turn or zoom is left (rung 0, the shift, keeps the
weight the bounded biharmonic solve gave the handle, so a translation carries what it
carried before). Blending neighbouring rungs rather than the whole map with the identity
keeps a turn from shrinking the sphere between them (a chord blend of a 90° turn with the
identity shrinks it by cos 45° half way) and a zoom from dipping.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..document.handles import REACH_RANGE, Handles, PointHandle
from ..sphere import coords
from ..sphere.moebius import Moebius
from .constraints import Constraints, Control
from .kinds import kind_of

__all__ = ["DEFAULT_REACH", "default_reach", "profiles", "reach_discs", "reach_samples", "rung_count", "rung_maps", "solved", "with_reach"]

#: The default reach (degrees) of a point handle with room around it; nearer other handles make it shorter.
DEFAULT_REACH = 15.0
#: The largest step (degrees of turn) between neighbouring rungs.
TURN_STEP = 7.5
#: The largest step (factor of zoom) between neighbouring rungs.
ZOOM_STEP = 1.12
#: The turn and zoom hold fully out to this share of the reach, a little beyond a third so
#: that the mesh's linear interpolation of the weights leaves them whole at a third.
INNER = 0.345
#: ... and are gone at this share, a little short of the reach for the same reason.
OUTER = 1.0
#: Rings of mesh vertices from ``INNER`` to ``OUTER`` times the reach, evenly in the log of the distance.
RINGS = 24
#: A point moved up to this share of its reach turns and zooms over the whole reach (its shift carried with the
#: turn and zoom within a third of it, fading evenly in distance out to the reach, which stretches the annulus by
#: about 1.5 x the shift / the reach: at most 0.5 here); moved farther, less and less, until at twice this share its
#: turn and zoom stay within the weight the bounded biharmonic solve gave its shift. Chosen on the even seeds of the
#: points and mixed families: the share of points that hold the asked zoom at a third of the reach against how near
#: a room's annulus comes to folding (bench/RESULTS.md, "a point handle's reach").
SHIFT_FREE = 0.33
#: The most rungs above the shift.
MAX_RUNGS = 12


def default_reach(handles: Handles, index: int) -> float:
    """A point handle's reach when its ``reach`` is not given: half the way to the nearest other handle, at most :data:`DEFAULT_REACH`.

    Parameters
    ----------
    handles : Handles
    index : int
        A point handle's index.

    Returns
    -------
    float
        Degrees, in :data:`~omniwidget.document.handles.REACH_RANGE`.
    """
    h = handles.handles[index]
    if not isinstance(h, PointHandle):
        raise TypeError(f"handles[{index}] is a {h.kind} handle, not a point")
    others: list[NDArray[np.float64]] = []
    t = np.linspace(0.0, 1.0, 33)
    for j, o in enumerate(handles.handles):
        if j != index:
            others.extend(kind_of(o).footprint(o, t))
    if not others:
        return DEFAULT_REACH
    nearest = float(np.min(coords.angular_distance(np.vstack(others), np.asarray(h.final, np.float64))))
    return float(np.clip(nearest / 2.0, REACH_RANGE[0], DEFAULT_REACH))


def profiles(tau: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The share of the zoom (as a power of the scale) and of the turn at ladder position ``tau``.

    Parameters
    ----------
    tau : ndarray of float64
        1 within a third of the reach, 0 at the reach and beyond; in between
        ``1 - ln(3 d / R) / ln 3`` at distance ``d``.

    Returns
    -------
    zoom, turn : ndarray of float64
        The turn falls evenly in ``ln d`` (a twist of constant shear, the least for a given
        turn); the zoom as ``log2(0.8 + 1.2 * 6 ** -(1 - tau))``, which falls fastest where
        it is still large, so that a zoom in never magnifies below 0.8 and a zoom out never
        above 1.25 on the way (the bound on the slope grows with the zoom left; see
        bench/RESULTS.md, "a point handle's reach").
    """
    tau = np.clip(np.asarray(tau, np.float64), 0.0, 1.0)
    return np.log2(0.8 + 1.2 * 6.0 ** -(1.0 - tau)), tau


def rung_count(scale: float, rotation: float) -> int:
    """How many rungs above the shift a turn and zoom need: steps of at most :data:`TURN_STEP` and :data:`ZOOM_STEP`."""
    n = max(abs(rotation) / TURN_STEP, abs(math.log(scale)) / math.log(ZOOM_STEP))
    return int(min(max(math.ceil(n - 1e-9), 1), MAX_RUNGS))


def rung_maps(h: PointHandle, n: int) -> list[Moebius]:
    """The ladder of a point handle, rung 0 (its shift) to rung ``n`` (its own map), ``n + 1`` maps."""
    taus = np.arange(n + 1) / n
    zoom, turn = profiles(taus)
    return [Moebius.point_map(h.position, h.final, h.scale ** float(z), h.rotation * float(u)) for z, u in zip(zoom, turn, strict=True)]


def _is_rung(control: Control) -> bool:
    return control.label.startswith(f"handles[{control.handle}] (point, ")


def solved(constraints: Constraints) -> Constraints:
    """The constraints without the ladders' controls: those the bounded biharmonic weights were solved for.

    ``with_reach(handles, solved(c), vertices, eased)`` gives back the blend's weights from the
    eased solve (``Deformation.raw_weights`` normalised and eased).
    """
    keep = [j for j, c in enumerate(constraints.controls) if not _is_rung(c)]
    if len(keep) == len(constraints.controls):
        return constraints
    return replace(constraints, controls=tuple(constraints.controls[j] for j in keep), values=constraints.values[:, keep])


def _stays(h: PointHandle, reach: float) -> float:
    """1 for a point whose turn and zoom fill its reach, falling to 0 for one moved twice :data:`SHIFT_FREE` times its reach."""
    moved = float(coords.angular_distance(h.position, h.final)) / reach
    return 1.0 - min(max(moved / SHIFT_FREE - 1.0, 0.0), 1.0)


def _reaching(handles: Handles) -> list[tuple[int, PointHandle, float]]:
    out = []
    for i, h in enumerate(handles.handles):
        if isinstance(h, PointHandle) and (h.scale != 1.0 or h.rotation != 0.0):
            out.append((i, h, h.reach if h.reach is not None else default_reach(handles, i)))
    return out


def reach_discs(handles: Handles) -> list[tuple[NDArray[np.float64], float]]:
    """Each turning or zooming point's reach as an output disc: its target (unit vector) and the reach, degrees.

    Every point with a turn or a zoom is listed, its ladder or not (a point moved far keeps its
    turn and zoom within its shift's weights, which are its own there too).
    """
    return [(coords.lonlat_to_xyz(h.final), reach) for _, h, reach in _reaching(handles)]


def reach_samples(handles: Handles) -> NDArray[np.float64]:
    """Unit vectors (m, 3) on rings inside each turning or zooming point's reach, to refine the mesh there.

    :data:`RINGS` rings from ``INNER`` to ``OUTER`` times the reach, evenly in the log of the
    distance, each of as many points as keep the mesh's triangles there about equilateral. A
    point moved twice :data:`SHIFT_FREE` times its reach or more gets none.
    """
    rings = []
    for _, h, reach in _reaching(handles):
        if _stays(h, reach) == 0.0:
            continue  # its turn and zoom stay within its shift's weight: the mesh as before
        centre = coords.lonlat_to_xyz(h.final)
        a = np.array([1.0, 0.0, 0.0]) if abs(centre[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(centre, a)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(centre, e1)
        radii = reach * np.geomspace(INNER, OUTER, RINGS)
        count = int(math.ceil(2.0 * math.pi * (RINGS - 1) / math.log(OUTER / INNER)))
        for r in radii:
            turn = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)[:, None]
            rr = math.radians(r)
            rings.append(math.cos(rr) * centre + math.sin(rr) * (np.cos(turn) * e1 + np.sin(turn) * e2))
    return np.vstack(rings) if rings else np.empty((0, 3))


def with_reach(
    handles: Handles, constraints: Constraints, vertices: NDArray[np.float64], weights: NDArray[np.float64]
) -> tuple[Constraints, NDArray[np.float64]]:
    """The controls and weights with each turning or zooming point handle's ladder.

    Parameters
    ----------
    handles : Handles
    constraints : Constraints
        With the still background's control last (:func:`~omniwidget.method.background.with_background`).
    vertices : ndarray of float64, shape (n, 3)
    weights : ndarray of float64, shape (n, k)
        Normalised and eased weights, the background's last.

    Returns
    -------
    constraints : Constraints
        The rungs' controls inserted before the background (``k + r`` controls).
    weights : ndarray of float64, shape (n, k + r)
        Rows still summing to 1. At a vertex at distance ``d`` from the target, with ``W``
        the handle's weight, ``o`` the other handles' (not the background's), ``tau`` the
        ladder position (:func:`profiles`) and ``s`` how fully the point reaches
        (:func:`_stays`: 1 for a point moved up to :data:`SHIFT_FREE` times its reach, 0 for
        one moved twice that or more, linear between), the handle's rungs share
        ``P = max(W, f s (1 - o))`` between the two rungs either side of ``n tau``, where
        ``f`` is 1 for a point that stays and, for one that moves, falls linearly in distance
        from 1 at a third of the reach to 0 at the reach (its shift's fade); the background
        gets ``1 - o - P`` and the other handles keep theirs. Rung 0 of a point that stays
        is the identity and goes to the background. For ``s < 1``, ``tau`` is also at most
        ``max(s, W / (1 - o))``: a point moved twice :data:`SHIFT_FREE` times its reach or
        more keeps its shift's weight as the solve gave it (raised over so short a fall for
        so long a move, it would fold the sphere), and its turn and zoom reach no farther
        than that weight.
    """
    reaching = _reaching(handles)
    if not reaching:
        return constraints, weights
    controls = list(constraints.controls[:-1])
    columns = [weights[:, c] for c in range(weights.shape[1] - 1)]
    background = weights[:, -1].copy()
    own = {c.handle: j for j, c in enumerate(controls) if c.label == f"handles[{c.handle}] (point)"}
    for i, h, reach in reaching:
        c = own[i]
        n = rung_count(h.scale, h.rotation)
        maps = rung_maps(h, n)
        centre = coords.lonlat_to_xyz(h.final)
        d = np.degrees(np.arccos(np.clip(vertices @ centre, -1.0, 1.0)))
        inner, outer = INNER * reach, OUTER * reach
        tau = np.clip(1.0 - np.log(np.maximum(d / inner, 1.0)) / math.log(outer / inner), 0.0, 1.0)
        w = columns[c]
        total = w + background
        other = np.clip(1.0 - total, 0.0, 1.0)
        free = 1.0 - other
        # a point moved far for its reach: the shift keeps its weight as the solve gave it (a
        # steeper fall would fold), and the turn and zoom stay within it; one moved up to
        # SHIFT_FREE times its reach reaches as one that stays, its shift carried with them
        stays = _stays(h, reach)  # 1: reaches fully, 0: within its shift's weight
        alone = np.divide(w, free, out=np.zeros_like(w), where=free > 1e-15)
        tau = np.minimum(tau, np.maximum(alone, stays))
        translated = not maps[0].isclose(Moebius.identity())
        # the rungs' share: for a shift, fading evenly in distance from a third of the reach to the reach (the
        # least stretch a move that ends at the reach makes); rung 0 is the identity otherwise, merged into the
        # background below, and then the share is all that is free
        fade = np.clip((outer - d) / (outer - inner), 0.0, 1.0) if translated else 1.0
        share = np.maximum(w, fade * free * stays)
        at = np.where(share > 1e-15, n * tau, 0.0)
        at = np.clip(at, 0.0, n)
        low = np.minimum(np.floor(at), n - 1)
        frac = at - low
        rungs = np.zeros((len(vertices), n + 1))
        rows = np.arange(len(vertices))
        rungs[rows, low.astype(int)] += share * (1.0 - frac)
        rungs[rows, low.astype(int) + 1] += share * frac
        background = np.clip(total - share, 0.0, 1.0)
        columns[c] = rungs[:, n]
        if translated:
            controls.append(Control(maps[0], i, f"handles[{i}] (point, shift)"))
            columns.append(rungs[:, 0])
        else:
            background = background + rungs[:, 0]
        for k in range(1, n):
            controls.append(Control(maps[k], i, f"handles[{i}] (point, rung {k} of {n})"))
            columns.append(rungs[:, k])
    controls.append(constraints.controls[-1])
    columns.append(background)
    out = np.stack(columns, axis=1)
    extra = len(controls) - len(constraints.controls)
    values = np.hstack([constraints.values[:, :-1], np.zeros((len(constraints.values), extra)), constraints.values[:, -1:]])
    return replace(constraints, controls=tuple(controls), values=values), out
