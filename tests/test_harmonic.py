"""The harmonic fill between the handles (omniwidget/method/harmonic.py: "no swirl").

What it promises, checked on generated rooms and on maps whose answer is known:

- held nodes keep the blend to the bit, and so does every output pixel whose four nodes are held: the marked
  lines (their pixels), cages' insides and points' discs show the blend of eq. (2) exactly;
- a blend that is one conformal map everywhere (the identity, or one Möbius map) is left as it is, to the grid's
  discretisation error;
- on a room of long lines, where the blend swirls, the filled map is measured less distorted than the blend alone,
  folds nothing, and keeps every line as straight;
- the paper's mode has no fill.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from omniwidget.document.handles import Handles, Options
from omniwidget.evaluate.scenes import family_scene
from omniwidget.method import harmonic
from omniwidget.method.deformation import deform
from omniwidget.raster.pipeline import warp
from omniwidget.raster.untangle import line_pixels
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

W = 512


def _warp(doc: Handles, image: np.ndarray, fill: bool, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(harmonic, "FILL", fill)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return warp(image, doc)


@pytest.fixture(scope="module")
def long_room():
    """A room of long lines (``long`` seed 3, held out) warped at 512 with the fill and without it."""
    room, doc, _ = family_scene("long", 3, W)
    mp = pytest.MonkeyPatch()
    try:
        with_fill, without = _warp(doc, room.image, True, mp), _warp(doc, room.image, False, mp)
    finally:
        mp.undo()
    return with_fill, without


def test_held_nodes_keep_the_blend_to_the_bit(long_room):
    fill = long_room[0].fill
    assert fill is not None
    assert 0.1 < (~fill.held).mean() < 0.9  # a fill with something to do, and something held
    assert np.array_equal(fill.filled[fill.held], fill.blend[fill.held])
    assert np.all(fill.held[[0, -1]])  # the rings round the poles


def test_pixels_of_the_lines_show_the_blend_exactly(long_room):
    with_fill, without = long_room
    m_fill, m_blend = with_fill.inverse_map(np.float64), without.inverse_map(np.float64)
    lon, lat = coords.grid_lonlat(W)
    touched = with_fill.fill.touched(lon, lat)
    assert touched.any() and not touched.all()
    lines = 0
    for c, samples in with_fill.constraints.lines:
        arc = float(coords.angular_distance(samples[0], samples[-1]))
        dense = coords.geodesic(samples[0], samples[-1], np.linspace(0.0, 1.0, int(4 * arc * W / 360) + 2))
        x, y = line_pixels(with_fill.controls[c].moebius(dense), W).T  # columns and rows
        assert not touched[y, x].any()
        assert np.array_equal(m_fill[y, x], m_blend[y, x])
        lines += 1
    assert lines >= 3
    # and the untouched pixels everywhere else too
    assert np.array_equal(m_fill[~touched], m_blend[~touched])


def test_the_fill_lowers_the_distortion_of_a_room_of_long_lines(long_room):
    with_fill, without = long_room
    q, q0 = with_fill.quality, without.quality
    print(
        f"\nlong seed 3 at {W}: distortion p99 {q0.distortion_p99:.3f} -> {q.distortion_p99:.3f}, "
        f"mean {q0.distortion_mean:.4f} -> {q.distortion_mean:.4f}; lines worst {max(q0.lines):.3f} -> {max(q.lines):.3f} px"
    )
    assert q.fold_over == 0 and with_fill.folds.area == 0
    assert q.distortion_p99 < 0.8 * q0.distortion_p99
    assert q.distortion_mean < q0.distortion_mean
    assert max(q.lines) <= max(q0.lines) + 1e-9  # the lines as straight as the blend makes them


def test_a_single_conformal_map_is_left_as_it_is():
    room, doc, _ = family_scene("long", 1, 128)
    d = deform(doc)
    for m, tolerance in ((Moebius.identity(), 1e-4), (Moebius.zoom([30.0, 10.0], 1.3), 0.06)):
        same = tuple(replace(c, moebius=m) for c in d.controls)
        fill = replace(d, constraints=replace(d.constraints, controls=same)).filled().fill
        assert fill is not None
        moved = np.degrees(np.arccos(np.clip(np.sum(fill.filled * fill.blend, axis=-1), -1, 1)))
        print(f"\n{m}: the fill moves the map by {moved.max():.2e} degrees at most")
        assert moved.max() < tolerance


def test_apply_gives_the_blend_where_every_node_is_held(long_room):
    fill = long_room[0].fill
    rng = np.random.default_rng(0)
    lonlat = np.stack([rng.uniform(-180, 180, 2000), rng.uniform(-89.9, 89.9, 2000)], axis=-1)
    blend = coords.lonlat_to_xyz(lonlat + rng.normal(scale=0.5, size=lonlat.shape))
    out = fill.apply(lonlat, blend)
    assert np.allclose(np.linalg.norm(out, axis=-1), 1.0)
    touched = np.array([fill.touched([lo], [la])[0, 0] for lo, la in lonlat])
    assert touched.any() and (~touched).any()
    assert np.array_equal(out[~touched], blend[~touched])


def test_the_papers_mode_has_no_fill():
    room, doc, _ = family_scene("long", 3, 128)
    d = deform(Handles(doc.handles, Options(rectify="all", anchor=None)))
    assert d.fill is None


def test_a_bad_grid_width_or_node_arrays_are_refused():
    room, doc, _ = family_scene("long", 1, 128)
    d = deform(doc)
    with pytest.raises(ValueError, match="even number of nodes"):
        harmonic.node_directions(7)
    n, k = harmonic.node_directions().shape[0] * harmonic.node_directions().shape[1], len(d.controls)
    with pytest.raises(ValueError, match=r"expected weights \("):
        harmonic.harmonic_fill(d.constraints, np.zeros((n, k + 1)), np.zeros((n, 3)))
