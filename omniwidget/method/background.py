"""The still background, our extension beyond the paper: the rest of the room stays where it was.

With ``options.anchor`` set (the default), the method gets one more control: the identity
map, :data:`BACKGROUND`. Mesh vertices far from every handle (:func:`with_background`)
get weight 1 for it, cages carry their inside by their own maps only
(:func:`cage_insides`, :func:`carry_insides`), and the handles' weights give way to it
soon and it takes over slowly (:func:`ease_background`). The least-motion choice of each
rectified line's map (``keep="sphere"`` in :mod:`.rectify`) belongs to it too. With
``"anchor": null`` none of this runs and the method is the paper's.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._lazy import lazy
from ..sphere import coords
from ..sphere.arcs import inside_polygon
from ..sphere.moebius import Moebius
from .constraints import POINT_HOLD, Constraints, Control

if TYPE_CHECKING:
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")

__all__ = [
    "ANCHOR_GROWTH",
    "BACKGROUND",
    "BACKGROUND_EASE",
    "Insides",
    "carry_insides",
    "cage_insides",
    "ease_background",
    "with_background",
]

#: Per cage: the mesh vertices inside its output polygon, and which controls may weigh there.
Insides = list[tuple[NDArray[np.int64], NDArray[np.bool_]]]


#: ``Control.handle`` of the still background (``Options.anchor``): the identity map.
BACKGROUND = -1
#: A control's anchor distance grows by this many times the farthest its map moves one of its own points.
ANCHOR_GROWTH = 2.0
#: Where the handles' weights sum to ``s < 1`` they get ``s ** BACKGROUND_EASE`` of it and the
#: still background the rest (:func:`ease_background`).
BACKGROUND_EASE = 3.0


def with_background(
    constraints: Constraints, vertices: NDArray[np.float64], anchor: float, insides: Insides
) -> tuple[Constraints, NDArray[np.int64], NDArray[np.float64]]:
    """The constraints with the still background's control added, and the mesh vertices whose weights it fixes.

    A vertex is still (weight 1 for the background) when it lies farther than its anchor
    distance from every control's prescribed points, ``anchor`` degrees plus
    :data:`ANCHOR_GROWTH` times the largest distance the control's map moves one of them (a
    point dragged far, a line bent much, reaches farther than a cage that holds still), and
    inside no cage. A vertex within :data:`~omniwidget.method.constraints.POINT_HOLD` of a
    point handle's target has weight 1 for that point's control.

    Returns
    -------
    constraints : Constraints
    fixed : ndarray of int64, shape (f,)
        Mesh vertices.
    values : ndarray of float64, shape (f, k + 1)
        Their weights.
    """
    owner = np.argmax(constraints.values, axis=1)
    still = np.ones(len(vertices), dtype=bool)
    for c in np.unique(owner):
        points = constraints.points[owner == c]
        moved = coords.angular_distance(
            coords.xyz_to_lonlat(points), coords.xyz_to_lonlat(constraints.controls[c].moebius.inverse.apply_xyz(points))
        )
        reach = min(anchor + ANCHOR_GROWTH * float(np.max(moved)), 180.0)
        distance, _ = spatial.cKDTree(points).query(vertices, distance_upper_bound=2.0 * math.sin(math.radians(reach) / 2.0))
        still &= ~np.isfinite(distance)
    for inside, _ in insides:
        still[inside] = False
    k = len(constraints.controls) + 1
    fixed, values = [np.flatnonzero(still)], [np.tile(np.eye(k)[-1], (int(still.sum()), 1))]
    chord = 2.0 * math.sin(math.radians(POINT_HOLD) / 2.0)
    for c, centre in constraints.disks:
        held = np.flatnonzero(np.linalg.norm(vertices - centre, axis=1) <= chord * (1 + 1e-9))
        fixed.append(held)
        values.append(np.tile(np.eye(k)[c], (len(held), 1)))
    background = Control(Moebius.identity(), BACKGROUND, "the still background")
    prescribed = np.hstack([constraints.values, np.zeros((len(constraints.values), 1))])
    constraints = replace(constraints, controls=(*constraints.controls, background), values=prescribed)
    return constraints, np.concatenate(fixed), np.vstack(values)


def cage_insides(constraints: Constraints, vertices: NDArray[np.float64]) -> Insides:
    """Per cage, the mesh vertices inside its output polygon and the controls that may have weight there.

    Those are the cage's own controls and any control with a prescribed point inside (a
    handle inside the cage); every other control's weight inside is set to 0 after the solve
    (:func:`carry_insides`), so a cage carries its inside by its own maps.
    """
    lonlat = coords.xyz_to_lonlat(vertices)
    prescribed = coords.xyz_to_lonlat(constraints.points)
    out = []
    for own, polygon in constraints.cages:
        inside = np.flatnonzero(inside_polygon(lonlat, polygon))
        keep = np.zeros(len(constraints.controls) + 1, dtype=bool)  # with the background's column
        keep[list(own)] = True
        within = inside_polygon(prescribed, polygon)
        keep[: len(constraints.controls)] |= (np.abs(constraints.values[within]) > 0).any(axis=0)
        out.append((inside, keep))
    return out


def carry_insides(weights: NDArray[np.float64], insides: Insides) -> NDArray[np.float64]:
    """Normalised weights with only the allowed controls inside each cage (their rows renormalised)."""
    weights = weights.copy()
    for inside, keep in insides:
        rows = weights[inside] * keep
        total = rows.sum(axis=1, keepdims=True)
        even = keep / keep.sum()
        weights[inside] = np.where(total > 1e-12, rows / np.maximum(total, 1e-300), even)
    return weights


def ease_background(weights: NDArray[np.float64], power: float = BACKGROUND_EASE) -> NDArray[np.float64]:
    """Let the handles' maps give way to the still background soon, and the background take over slowly.

    Parameters
    ----------
    weights : ndarray of float64, shape (n, k)
        Normalised weights per mesh vertex, the background's in the last column.
    power : float
        At least 1 (1 changes nothing).

    Returns
    -------
    ndarray of float64, shape (n, k)
        Rows that still sum to 1: the handles' share ``s = 1 - w_background`` becomes
        ``s ** power``, split among the handles as before; the background takes the rest.
        Where a handle's weight is 1 or 0 it stays so: every boundary condition holds.

    Notes
    -----
    Between a handle and the still region the blend's Jacobian is the identity plus about
    ``(M(p) - p) ⊗ ∇w``: its distortion is the handle's motion times the gradient of its
    weight. The motion of a Möbius map grows away from its handle (a line's fastest: it
    bends), so the weight should fall steeply close to the handle, where the map hardly
    moves the sphere, and slowly farther out. Bounded biharmonic weights fall about evenly;
    this power moves their fall towards the handle, which lowers the distortion's 99th
    percentile and the mean displacement (``bench/bench_line_maps.py`` measures both).
    """
    if power < 1:
        raise ValueError(f"power must be at least 1, got {power}")
    share = 1.0 - weights[:, -1]
    eased = np.clip(share, 0.0, 1.0) ** power
    out = weights.copy()
    out[:, :-1] *= np.divide(eased, share, out=np.zeros_like(share), where=share > 0)[:, None]
    out[:, -1] = 1.0 - eased
    return out
