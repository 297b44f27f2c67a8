"""The vectorised merging of omniwidget.detect.lines against plain loops that say the same.

:func:`~omniwidget.detect.lines.merge_arcs`, :func:`~omniwidget.detect.lines.pair_bands` and
:func:`~omniwidget.detect.lines.snap_ends` look only at the arcs a grid of their points finds
near each one; the loops below (the functions as they were, kept as the reference) test every arc each
time. Both must give the same arcs in the same order: on random arcs built to merge, on
generated rooms and on the panoramas of ``../shared/data``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

import omniwidget as ow
from omniwidget.detect import lines
from omniwidget.detect.lines import BAND_DISTANCE, MAX_ARC, MERGE_DISTANCE, MERGE_GAP, SNAP_REACH, Arc, _unit
from omniwidget.detect.vertical import INLIER_SIGMAS, _Edges, _passes_by, _scores
from omniwidget.evaluate.scenes import synthetic_room
from tests import requires

FloatArray = NDArray[np.float64]
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
#: The panoramas of ../shared/data (test inputs beside the checkout), named so that a missing one is said, not
#: collected as nothing.
PHOTOS = ("brooklyn_street_12k", "city_parking", "courtyard", "grabodrertorv", "hotel_room", "lamppost", "studio_office")

# --- the reference: the merging written as plain loops ----------------------


def _loop_merge_arcs(
    a: FloatArray,
    b: FloatArray,
    contrast: FloatArray,
    *,
    distance: float = MERGE_DISTANCE,
    gap: float = MERGE_GAP,
    polarity: bool = True,
) -> list[Arc]:
    """Merge arcs of one great circle whose extents overlap or nearly touch into one arc each.

    Greedy, longest first: the longest arc not yet taken seeds a cluster; every arc of the
    same polarity (the detector orients each segment by the side that is darker, so the
    arc's normal ``a x b`` tells the side) whose endpoints and midpoint lie within
    ``distance`` degrees of the cluster's great circle and whose extent along it comes within ``gap`` degrees of the cluster's joins it; the
    circle is refitted to all members' points (the smallest eigenvector of their scatter,
    weighted by length) and the search repeats until nothing joins.

    Parameters
    ----------
    a, b : ndarray of float64, shape (k, 3)
        Unit vectors of the arcs' endpoints.
    contrast : ndarray of float64, shape (k,)
    distance, gap : float
        Degrees.
    polarity : bool
        Merge only arcs of the same polarity (False: any).

    Returns
    -------
    list of Arc
        Oriented like their members, ``start x end`` along the members' normals.
    """
    k = len(a)
    if k == 0:
        return []
    mid = _unit(a + b)
    length = np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))
    sample_t = np.linspace(0.0, 1.0, 5)
    samples = _unit(a[:, None, :] * (1 - sample_t)[None, :, None] + b[:, None, :] * sample_t[None, :, None])  # (k, 5, 3) chords, normalised
    sin_d = math.sin(math.radians(distance))
    gap_r = math.radians(gap)
    free = np.ones(k, dtype=bool)
    out: list[Arc] = []
    for seed in np.argsort(-length):
        if not free[seed]:
            continue
        members = np.zeros(k, dtype=bool)
        members[seed] = True
        free[seed] = False
        normal = _unit(np.cross(a[seed], b[seed]))
        origin = a[seed]
        lo, hi = 0.0, float(length[seed])
        for _ in range(4):
            cand = np.flatnonzero(free)
            if cand.size == 0:
                break
            near = (np.abs(a[cand] @ normal) < sin_d) & (np.abs(b[cand] @ normal) < sin_d) & (np.abs(mid[cand] @ normal) < sin_d)
            if polarity:  # the same polarity: the dark side on the same side
                near &= np.cross(a[cand], b[cand]) @ normal > 0
            cand = cand[near]
            if cand.size == 0:
                break
            other = np.cross(normal, origin)
            ta = np.arctan2(a[cand] @ other, a[cand] @ origin)
            tb = np.arctan2(b[cand] @ other, b[cand] @ origin)
            c_lo, c_hi = np.minimum(ta, tb), np.maximum(ta, tb)
            joins = (c_lo <= hi + gap_r) & (c_hi >= lo - gap_r) & (c_hi - c_lo < math.pi)
            joins &= np.maximum(hi, c_hi) - np.minimum(lo, c_lo) < MAX_ARC  # an arc is the shorter way between its ends
            if not joins.any():
                break
            new = cand[joins]
            members[new] = True
            free[new] = False
            lo, hi = min(lo, float(c_lo[joins].min())), max(hi, float(c_hi[joins].max()))
            normal = _loop_refit(samples[members], length[members], normal)
            origin = _unit(origin - (origin @ normal) * normal)
        out.append(_loop_finish(a[members], b[members], length[members], contrast[members], normal, origin))
    return out


def _loop_pair_bands(arcs: Sequence[Arc], *, distance: float = BAND_DISTANCE, overlap: float = 0.5) -> list[Arc]:
    """Replace the two borders of each painted band or thin dark (or light) line by its midline.

    A thin line a few pixels wide is found as two parallel edges of opposite polarity, a
    little apart. Pairs of arcs of opposite polarity whose points lie within ``distance``
    degrees of each other's great circles and whose extents overlap by at least ``overlap``
    of the shorter become one arc along the bisecting great circle, over the union of
    their extents. Arcs without such a partner are kept as they are.

    Parameters
    ----------
    arcs : sequence of Arc
        From :func:`merge_arcs` (oriented).
    distance : float
        Degrees.
    overlap : float
        Share of the shorter arc, in ``[0, 1]``.

    Returns
    -------
    list of Arc
    """
    k = len(arcs)
    if k == 0:
        return []
    a = np.array([arc.start for arc in arcs])
    b = np.array([arc.end for arc in arcs])
    normal = _unit(np.cross(a, b))
    mid = _unit(a + b)
    length = np.array([arc.length for arc in arcs])
    sin_d = math.sin(math.radians(distance))
    taken = np.zeros(k, dtype=bool)
    out: list[Arc] = []
    for i in np.argsort(-length):
        if taken[i]:
            continue
        taken[i] = True
        cand = np.flatnonzero(~taken & (normal @ normal[i] < 0))
        near = (np.abs(a[cand] @ normal[i]) < sin_d) & (np.abs(b[cand] @ normal[i]) < sin_d) & (np.abs(mid[cand] @ normal[i]) < sin_d)
        near &= (np.abs(normal[cand] @ a[i]) < sin_d) & (np.abs(normal[cand] @ b[i]) < sin_d)
        cand = cand[near]
        best, best_overlap = -1, 0.0
        other = np.cross(normal[i], a[i])
        for j in cand:
            ta = math.atan2(float(a[j] @ other), float(a[j] @ a[i]))
            tb = math.atan2(float(b[j] @ other), float(b[j] @ a[i]))
            shared = min(max(ta, tb), math.radians(length[i])) - max(min(ta, tb), 0.0)
            share = shared / math.radians(min(length[i], length[j]))
            if share >= overlap and share > best_overlap:
                best, best_overlap = int(j), share
        if best < 0:
            out.append(arcs[i])
            continue
        taken[best] = True
        bisector = _unit(normal[i] - normal[best])
        origin = _unit(a[i] - (a[i] @ bisector) * bisector)
        pair = np.array([i, best])
        ends_a = np.array([a[i], b[best]])  # b of the opposite arc runs the same way as a of this one
        ends_b = np.array([b[i], a[best]])
        merged = _loop_finish(ends_a, ends_b, length[pair], np.array([arcs[i].contrast, arcs[best].contrast]), bisector, origin)
        coverage = max(arcs[i].coverage * length[i], arcs[best].coverage * length[best]) / max(merged.length, 1e-9)
        out.append(Arc(merged.start, merged.end, merged.contrast, min(1.0, coverage), arcs[i].pieces + arcs[best].pieces))
    return out


def _loop_refit(points: NDArray, weights: NDArray, previous: FloatArray) -> FloatArray:
    """The unit normal of the great circle best through ``points`` (k, s, 3), weighted per arc, signed like ``previous``."""
    flat = points.reshape(-1, 3)
    w = np.repeat(weights / points.shape[1], points.shape[1])
    scatter = (flat * w[:, None]).T @ flat
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return normal if normal @ previous >= 0 else -normal


def _loop_finish(a: NDArray, b: NDArray, length: NDArray, contrast: NDArray, normal: FloatArray, origin: FloatArray) -> Arc:
    """The merged arc: the members' extent projected on the fitted circle, and its support."""
    other = np.cross(normal, origin)
    ta = np.arctan2(a @ other, a @ origin)
    tb = np.arctan2(b @ other, b @ origin)
    lo_each, hi_each = np.minimum(ta, tb), np.maximum(ta, tb)
    lo, hi = float(lo_each.min()), float(hi_each.max())
    # covered share of [lo, hi]: the union of the members' intervals
    order = np.argsort(lo_each)
    covered, reach = 0.0, lo
    for i in order:
        start, stop = max(float(lo_each[i]), reach), float(hi_each[i])
        if stop > start:
            covered += stop - start
            reach = stop
    span = hi - lo
    start_v = math.cos(lo) * origin + math.sin(lo) * other
    end_v = math.cos(hi) * origin + math.sin(hi) * other
    weight = np.maximum(length, 1e-12)
    return Arc(
        start=start_v,
        end=end_v,
        contrast=float(np.sum(contrast * weight) / np.sum(weight)),
        coverage=float(min(1.0, covered / span)) if span > 0 else 1.0,
        pieces=len(a),
    )


def _loop_snap_ends(arcs: Sequence[Arc], reach: float = SNAP_REACH) -> list[Arc]:
    """Move each arc's ends to the junction they stop short of.

    A detector stops a few pixels short of where two edges meet (the gradient turns
    there). When another arc's great circle crosses this arc's circle within ``reach``
    degrees of an end, and that crossing lies on (or within ``reach`` of) the other arc,
    the end moves to the nearest such crossing: along its own circle, so the arc stays on
    its edge.

    Parameters
    ----------
    arcs : sequence of Arc
    reach : float
        Degrees.

    Returns
    -------
    list of Arc
    """
    if len(arcs) < 2:
        return list(arcs)
    a = np.array([arc.start for arc in arcs])
    b = np.array([arc.end for arc in arcs])
    normal = _unit(np.cross(a, b))
    length = np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))
    other = np.cross(normal, a)
    cos_reach = math.cos(math.radians(reach))
    reach_r = math.radians(reach)
    out = []
    for i, arc in enumerate(arcs):
        ends = [arc.start, arc.end]
        crossing = np.cross(normal[i], normal)  # (k, 3): where circle i meets each circle
        size = np.linalg.norm(crossing, axis=1)
        usable = size > math.sin(math.radians(10.0))  # circles that cross at a clear angle
        usable[i] = False
        if not usable.any():
            out.append(arc)
            continue
        x = crossing[usable] / size[usable, None]
        idx = np.flatnonzero(usable)
        for e in range(2):
            end = ends[e]
            xs = x * np.where(x @ end < 0, -1.0, 1.0)[:, None]
            close = xs @ end > cos_reach
            t = np.arctan2(np.einsum("ij,ij->i", xs, other[idx]), np.einsum("ij,ij->i", xs, a[idx]))
            on_other = (t > -reach_r) & (t < length[idx] + reach_r)
            ok = close & on_other
            if ok.any():
                best = int(np.argmax(np.where(ok, xs @ end, -2.0)))
                ends[e] = xs[best]
        out.append(Arc(ends[0], ends[1], arc.contrast, arc.coverage, arc.pieces))
    return out


# --- the comparisons -----------------------------------------------------------------


def _table(arcs: Sequence[Arc]) -> FloatArray:
    """One row per arc: start, end, contrast, coverage, pieces."""
    return np.array([[*arc.start, *arc.end, arc.contrast, arc.coverage, arc.pieces] for arc in arcs]).reshape(-1, 9)


def _same_arcs(got: Sequence[Arc], want: Sequence[Arc], tolerance: float = 1e-12) -> None:
    assert len(got) == len(want)
    np.testing.assert_allclose(_table(got), _table(want), rtol=0, atol=tolerance)


def _random_arcs(seed: int, circles: int = 60, noise: int = 400) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pieces of a few great circles (both polarities, overlapping, with gaps near MERGE_GAP, off the circle near
    MERGE_DISTANCE, some across ±180° of their circle), and arcs strewn at random, shuffled."""
    rng = np.random.default_rng(seed)
    a_list, b_list = [], []
    for _ in range(circles):
        normal = _unit(rng.normal(size=3))
        origin = _unit(np.cross(normal, rng.normal(size=3)))
        other = np.cross(normal, origin)
        start = rng.uniform(-math.pi, math.pi)
        for _ in range(int(rng.integers(2, 12))):
            t0 = start + rng.uniform(-0.3, 0.5)
            t1 = t0 + rng.choice([rng.uniform(0.002, 0.05), rng.uniform(0.05, 0.6), rng.uniform(0.6, 1.8)])
            start = t1 + rng.uniform(-0.02, 0.09)  # the next piece overlaps, touches or stops a few degrees short
            ends = []
            for t in (t0, t1):
                off = rng.uniform(-1.2, 1.2) * math.radians(MERGE_DISTANCE)
                ends.append(_unit(math.cos(t) * origin + math.sin(t) * other + off * normal))
            if rng.random() < 0.3:
                ends.reverse()  # the other polarity
            a_list.append(ends[0])
            b_list.append(ends[1])
    for _ in range(noise):
        p = _unit(rng.normal(size=3))
        q = _unit(p + rng.uniform(0.005, 0.4) * _unit(np.cross(p, rng.normal(size=3))))
        a_list.append(p)
        b_list.append(q)
    order = rng.permutation(len(a_list))
    a, b = np.array(a_list)[order], np.array(b_list)[order]
    return a, b, rng.uniform(0.02, 0.5, len(a))


@pytest.mark.parametrize("seed", range(6))
def test_merge_matches_the_loop_on_random_arcs(seed):
    a, b, contrast = _random_arcs(seed)
    for options in ({}, {"polarity": False}, {"distance": lines.FINAL_DISTANCE, "polarity": False}, {"distance": 2.0, "gap": 8.0}):
        merged = lines.merge_arcs(a, b, contrast, **options)
        _same_arcs(merged, _loop_merge_arcs(a, b, contrast, **options))
        assert sum(arc.pieces for arc in merged) == len(a)
    merged = _loop_merge_arcs(a, b, contrast)
    assert any(arc.pieces > 2 for arc in merged)  # the arcs do merge
    _same_arcs(lines.pair_bands(merged), _loop_pair_bands(merged))
    _same_arcs(lines.pair_bands(merged, distance=5.0, overlap=0.0), _loop_pair_bands(merged, distance=5.0, overlap=0.0))
    _same_arcs(lines.snap_ends(merged), _loop_snap_ends(merged), tolerance=0.0)
    _same_arcs(lines.snap_ends(merged, reach=6.0), _loop_snap_ends(merged, reach=6.0), tolerance=0.0)


def test_merge_of_few_arcs():
    a, b, contrast = _random_arcs(0, circles=1, noise=0)
    for n in (0, 1, 2):
        _same_arcs(lines.merge_arcs(a[:n], b[:n], contrast[:n]), _loop_merge_arcs(a[:n], b[:n], contrast[:n]))
        arcs = _loop_merge_arcs(a[:n], b[:n], contrast[:n])
        _same_arcs(lines.pair_bands(arcs), _loop_pair_bands(arcs))
        _same_arcs(lines.snap_ends(arcs), _loop_snap_ends(arcs))


class _Loops:
    """:func:`omniwidget.detect.lines.find_arcs` with the reference loops in place of the merging (a context)."""

    def __enter__(self) -> None:
        self.saved = lines.merge_arcs, lines.pair_bands, lines.snap_ends
        lines.merge_arcs, lines.pair_bands, lines.snap_ends = _loop_merge_arcs, _loop_pair_bands, _loop_snap_ends

    def __exit__(self, *exc: object) -> None:
        lines.merge_arcs, lines.pair_bands, lines.snap_ends = self.saved


def _same_suggestions(image: NDArray, tolerance: float = 1e-8) -> int:
    """Every suggestion of ``image``, by the loops and as now: the same lines to rounding, in the same order; how many."""
    new = ow.suggest_lines(image, max_lines=None, structure=False)  # every line found: the merging's work
    with _Loops():
        old = ow.suggest_lines(image, max_lines=None, structure=False)
    assert len(new) == len(old)
    row = lambda s: [*s.start, *s.end, s.length, s.contrast, s.confidence]  # noqa: E731
    np.testing.assert_allclose(np.array([row(s) for s in new]), np.array([row(s) for s in old]), rtol=0, atol=tolerance)
    return len(new)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_suggestions_match_the_loops_on_rooms(seed):
    rng = np.random.default_rng(seed)
    pitch, roll = rng.uniform(-15, 15, 2)
    scene = synthetic_room(768, grid=[None, 1.0, 1.5][seed], noise=4.0, seed=seed, pitch=pitch, roll=roll, yaw=rng.uniform(0, 90))
    assert _same_suggestions(scene.image) >= 8


def test_suggestions_match_the_loops_on_a_photo():
    # the bundled hotel room (the CC0 copy of ../shared/data's, the same pixels): always there
    assert _same_suggestions(ow.sample_image()) > 100


@pytest.mark.slow
@pytest.mark.parametrize("name", PHOTOS)
def test_suggestions_match_the_loops_on_every_photo(name):
    from omniwidget.io.images import read_panorama

    path = DATA / f"{name}.jpg"
    if not path.exists():  # skipped on a checkout alone; a failure where everything must be there (CI)
        requires.missing(f"{path} is a test input beside the checkout (../shared/data)")
    assert _same_suggestions(read_panorama(path)) > 100


def test_one_thread_finds_the_same_arcs(monkeypatch):
    image = synthetic_room(512, noise=3.0, seed=5, pitch=4.0).image
    gray = lines.panorama_gray(image)
    threaded = lines.find_arcs(gray)
    monkeypatch.setattr(lines.os, "cpu_count", lambda: 1)
    _same_arcs(lines.find_arcs(gray), threaded, tolerance=0.0)


def test_view_maps_are_the_rays_lonlat_and_pixels():
    """The maps written out on planes are those of View.rays, xyz_to_lonlat and lonlat_to_px, to the bit."""
    from omniwidget.sphere import coords

    for width in (64, 512, 1000, 1024, 2048, 2050):
        for view in lines.cube_views(width):
            grid = np.mgrid[0 : view.size, 0 : view.size][::-1].transpose(1, 2, 0)
            px = coords.lonlat_to_px(coords.xyz_to_lonlat(view.rays(grid)), width)
            map_x, map_y = lines._view_maps(view, width, width // 2)
            assert np.array_equal(map_x, np.mod(px[..., 0], width).astype(np.float32))
            assert np.array_equal(map_y, np.clip(px[..., 1], 0, width // 2 - 1).astype(np.float32))


def test_grid_finds_every_point_within_the_angle():
    rng = np.random.default_rng(3)
    points = _unit(rng.normal(size=(3000, 3)))
    points[:40] = _unit(np.array([[0.0, 0.0, 1.0]]) + 1e-3 * rng.normal(size=(40, 3)))  # at a pole
    points[40:80] = _unit(np.array([[1.0, 0.0, 0.0]]) + 1e-3 * rng.normal(size=(40, 3)))  # at a face of the cube
    grid = lines._EndTree(points[:1500], points[1500:])
    centres = _unit(np.concatenate([points[:100] + 0.01 * rng.normal(size=(100, 3)), rng.normal(size=(100, 3))]))
    angles = rng.choice([0.01, 0.05, 0.2, 1.0, 3.0], len(centres))
    which, owner = grid.query(centres, angles)
    for i, (centre, angle) in enumerate(zip(centres, angles, strict=True)):
        within = np.arccos(np.clip(points @ centre, -1.0, 1.0)) <= angle
        want = set((np.flatnonzero(within) % 1500).tolist())
        got = set(owner[which == i].tolist())
        assert want <= got
        assert got == set(grid.near(centre, float(angle)).tolist())
        close = np.arccos(np.clip(points @ centre, -1.0, 1.0)) <= angle + lines._TREE_MARGIN + 1e-6
        assert got <= set((np.flatnonzero(close) % 1500).tolist())  # and no arc without a point in the ball


def test_grid_finds_every_point_near_a_circle():
    """A query with circles keeps exactly the points within the angle that lie within the band: the cubes it skips hold none."""
    rng = np.random.default_rng(4)
    centres = _unit(rng.normal(size=(300, 3)))
    circles = _unit(np.cross(centres, rng.normal(size=(300, 3))))  # circles through the centres
    # points strewn at random, at a pole, and along the edges of the first band, just inside (|p . c| = 0.99999 band)
    t = np.linspace(-0.5, 0.5, 3000)[:, None]
    along = np.cos(t) * centres[200] + np.sin(t) * np.cross(circles[200], centres[200])
    edge = math.sin(math.radians(MERGE_DISTANCE)) * 0.99999
    edges = [_unit(along + side * math.tan(math.asin(edge)) * circles[200]) for side in (-1.0, 1.0)]
    points = np.concatenate([_unit(rng.normal(size=(4000, 3))), *edges])
    points[:50] = _unit(np.array([[0.0, 0.0, 1.0]]) + 1e-3 * rng.normal(size=(50, 3)))  # at a pole
    grid = lines._EndTree(points)
    circles[:40, 2] = 0.0  # normals flat in z: the columns' whole height
    circles[40:60, 2] = rng.choice([1e-7, -1e-7, 2e-6, -2e-6], 20)
    circles[:60] = _unit(circles[:60])
    circles[60:80] = rng.choice([-1.0, 1.0], (20, 1)) * np.array([0.0, 0.0, 1.0])  # the equator and the like
    angles = rng.choice([0.02, 0.1, 0.4, 1.5, 3.2], len(centres))
    for band in (math.sin(math.radians(MERGE_DISTANCE)), 0.1):
        which, owner = grid.query(centres, angles, circles, band)
        plain_which, plain_owner = grid.query(centres, angles)
        # the same as the ball's points filtered by the band afterwards, in the same order
        kept = np.abs(np.einsum("ij,ij->i", points[plain_owner], circles[plain_which])) < band
        assert np.array_equal(which, plain_which[kept])
        assert np.array_equal(owner, plain_owner[kept])
        assert len(which) > 100
    # the sharpest case: a point at a corner of its column's square, just inside the band of a circle through it
    corner = rng.integers(1, 19, size=(400, 2)) * lines._GRID_CELL - 1.0
    corner = corner[np.hypot(corner[:, 0], corner[:, 1]) < 0.99]
    at = np.column_stack([corner, rng.choice([-1.0, 1.0], len(corner)) * np.sqrt(1.0 - (corner**2).sum(axis=1))])
    # and at corners of cubes, all three coordinates on the grid's planes, each with many circles
    cubes = [np.roll([sx * 0.6, sy * 0.8, 0.0], r) for sx in (-1, 1) for sy in (-1, 1) for r in range(3)]
    cubes += [np.roll([sx * 1.0, 0.0, 0.0], r) for sx in (-1, 1) for r in range(3)]
    at = np.concatenate([at, np.repeat(np.array(cubes), 40, axis=0)])
    inside = math.sin(math.radians(MERGE_DISTANCE)) * (1.0 - 1e-7)
    across = _unit(np.cross(at, rng.normal(size=at.shape)))
    tilted = across * math.sqrt(1.0 - inside**2) + at * inside  # |at . tilted| = inside
    tilted[: len(tilted) // 4, 2] = 0.0  # some flat in z (then no longer just inside: kept or not, as the plain query says)
    grid = lines._EndTree(at)
    which, owner = grid.query(at, 0.01, tilted, math.sin(math.radians(MERGE_DISTANCE)))
    plain_which, plain_owner = grid.query(at, 0.01)
    kept = np.abs(np.einsum("ij,ij->i", at[plain_owner], tilted[plain_which])) < math.sin(math.radians(MERGE_DISTANCE))
    assert np.array_equal(which, plain_which[kept]) and np.array_equal(owner, plain_owner[kept])
    assert np.count_nonzero(which == owner) > 200  # each finds itself


def test_level_scores_are_the_dense_sums():
    """level's candidate scores, summed over the few arcs near each candidate, are those of the whole table, to the bit."""
    scene = synthetic_room(768, grid=1.0, noise=3.0, seed=2, pitch=6.0, roll=-3.0)
    suggestions = [s for s in ow.suggest_lines(scene.image, max_lines=None, structure=False) if s.length >= 5.0]
    from omniwidget.sphere import coords

    a = coords.lonlat_to_xyz(np.array([s.start for s in suggestions]))
    b = coords.lonlat_to_xyz(np.array([s.end for s in suggestions]))
    normals = _unit(np.cross(a, b))
    along = np.cross(normals, a)
    spans = np.radians([s.length for s in suggestions])
    rng = np.random.default_rng(0)
    v = _unit(np.array([0.1, -0.05, 1.0]) + 0.2 * rng.normal(size=(3000, 3))).T
    sigma = rng.uniform(0.0005, 0.01, len(a))
    cap, polar = math.sin(math.radians(1.0)), math.cos(math.radians(20.0))
    r = np.arcsin(np.clip(np.abs(normals @ v), 0.0, 1.0))
    far = ~_passes_by(a, along, spans, v) & (np.maximum(np.abs(a @ v), np.abs(b @ v)) < polar)
    dense = (((r < INLIER_SIGMAS * sigma[:, None]) & (r < cap) & far) / sigma[:, None]).sum(axis=0)
    edges = _Edges(normals, a, b, along, spans, np.degrees(spans), _unit(a + b), np.ones(len(a)))
    got = _scores(edges, v, sigma, cap, polar)
    assert np.count_nonzero(dense) > 100
    assert np.array_equal(got, dense)
