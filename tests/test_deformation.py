"""The deformation and the warp's result by composition: one optional blend, a result that holds its deformation.

A deformation either has a :class:`~omniwidget.method.deformation.Blend` (the mesh, its
boundary conditions, the weights, the fill) or none (one map does it all); a
:class:`~omniwidget.raster.pipeline.Result` holds the deformation it warped by and reads its
attributes from it; a comparison method's result holds that method's deformation.
"""

from __future__ import annotations

import numpy as np
import pytest

from omniwidget.document.handles import Handles, LineHandle, Options, PointHandle
from omniwidget.evaluate.baselines import BaselineDeformation, BaselineResult, gaussian_2017
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.method.deformation import Blend, Deformation, deform, levelled_handles
from omniwidget.raster.pipeline import Result, warp
from omniwidget.sphere import coords

PARTS = ("vertices", "faces", "constrained", "prescribed", "weights", "raw_weights", "fill")
TWO = (LineHandle((-60.0, 30.0), (60.0, 30.0)), PointHandle((120.0, -10.0), target=(125.0, -5.0)))


@pytest.fixture(scope="module")
def room():
    return synthetic_room(256).image


@pytest.mark.parametrize("anchor", [5.0, None], ids=["still background", "paper"])
def test_a_deformation_has_a_blend_with_every_part_or_none(anchor):
    blended = deform(Handles(TWO, Options(anchor=anchor)))
    assert isinstance(blended.blend, Blend)
    for name in PARTS:
        assert getattr(blended, name) is getattr(blended.blend, name), name
    n, k = blended.blend.weights.shape
    assert blended.blend.vertices.shape == (n, 3) and k == len(blended.controls)
    assert blended.blend.prescribed.shape == (len(blended.blend.constrained), blended.blend.raw_weights.shape[1])
    assert (blended.fill is not None) == (anchor is not None)  # the fill is the default mode's
    held = LineHandle((-60.0, 30.0), (60.0, 30.0), rectify=False)  # held as it is: the identity does it all
    single = deform(Handles((held,), Options(anchor=anchor)))
    assert single.blend is None and all(getattr(single, name) is None for name in PARTS)


def test_the_result_holds_the_deformation_it_warped_by(room):
    doc = Handles(TWO)
    result = warp(room, doc, warn=False)
    d = result.deformation
    assert type(d) is Deformation and result.handles is doc is d.handles
    assert result.blend is d.blend and result.constraints is d.constraints and result.controls == d.controls
    for name in PARTS:
        assert getattr(result, name) is getattr(d, name), name
    lon, lat = coords.grid_lonlat(64)
    points = np.stack(np.meshgrid(lon[::7], lat[::5]), axis=-1)
    assert np.array_equal(result.inverse_points(points), d.inverse_points(points))
    assert np.array_equal(result.forward_points(points[0], 0), d.forward_points(points[0], 0))
    # the result's problems and timings are the deformation's and then the warp's own
    assert result.problems[: len(d.problems)] == d.problems
    assert set(d.timings) < set(result.timings) and "resampling" in result.timings
    # a warm start reads the deformation: the same problem solved again takes its weights as they are
    again = warp(room, doc, warn=False, previous=result)
    assert again.raw_weights is result.raw_weights and again.deformation is not d


def test_one_map_warps_without_a_blend(room):
    result = warp(room, Handles(TWO[1:], Options(anchor=None)), warn=False)  # the paper: one point, its map everywhere
    assert result.blend is None and result.coordinates is None and result.moebius is not None
    assert result.deformation.blend is None and result.weights is None


def test_a_baseline_result_holds_its_method_s_deformation(room):
    result = gaussian_2017(room, Handles(TWO))
    assert isinstance(result, BaselineResult) and isinstance(result, Result)
    assert type(result).__mro__[1] is Result  # a result, not a deformation too
    d = result.deformation
    assert isinstance(d, BaselineDeformation) and d.blend is None and result.method == d.method == "gaussian_2017"
    lon, lat = coords.grid_lonlat(256)
    at = result.inverse_points(np.stack([lon[[10, 200]], lat[[40, 90]]], axis=-1))
    shown = result.inverse_map(np.float64)[[40, 90], [10, 200]]
    diff = at - shown
    diff[..., 0] = coords.wrap_lon(diff[..., 0])
    assert np.abs(diff).max() < 1e-9  # the method's own map at points, as on its grid
    assert np.array_equal(result.pixel_weights(slice(0, 4)), d.pixel_weights(slice(0, 4)))
    with pytest.raises(ValueError, match=r"expected \[lon, lat\] pairs"):
        result.inverse_points(np.zeros((3, 3)))


def test_a_levelled_document_reuses_its_previous_solve_and_turns_its_blend(room):
    doc = Handles(TWO, Options(up=(20.0, 80.0)))
    first = warp(room, doc, warn=False)
    again = warp(room, doc, warn=False, previous=first)
    assert first.blend is not None and again.raw_weights is first.raw_weights  # the same weights problem: taken as it is
    assert np.array_equal(again.image, first.image)
    levelled = deform(levelled_handles(doc), upright=True)
    assert levelled.handles.options.up is None and levelled.blend is not None
    # every map starts with the levelling turn; the weights (on the output sphere) are the levelled solve's
    assert np.array_equal(first.weights, levelled.weights)
    turn = doc.options.levelling()
    assert all(a.moebius.isclose(b.moebius @ turn) for a, b in zip(first.controls, levelled.controls, strict=True))
