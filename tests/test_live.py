"""The live drag's basis (omniwidget.raster.live): eq. (2) split so that the browser redoes it per frame.

The browser's per-pixel sum is :meth:`LiveBasis.inverse_lonlat`; here it is checked against
the kernel's own blend, with the maps the result has and with new maps where the weights
stay the same. The editor's side: the basis sent, and a drag's solves that are no edit.
"""

from __future__ import annotations

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from omniwidget.raster import _kernels
from omniwidget.raster.live import REGION_WEIGHT, live_basis
from omniwidget.raster.pipeline import warp
from omniwidget.sphere import coords
from tests.conftest import offset

WIDTH = 256


def _scene(anchor) -> Handles:
    return Handles(
        (
            PointHandle((20.0, 5.0)),
            LineHandle((-70.0, 30.0), (-30.0, 36.0)),
            CageHandle(((100.0, -10.0), (130.0, -10.0), (115.0, 15.0))),
            PointHandle((175.0, -20.0), (-178.0, -18.0)),  # across the seam
        ),
        options=Options(anchor=anchor),
    )


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return ow.read_image(ow.sample_path())


def _region_of(full: np.ndarray, basis) -> np.ndarray:
    row, col = basis.origin
    height, width = basis.fixed.shape[:2]
    return full[row : row + height][:, (col + np.arange(width)) % basis.size]


@pytest.mark.parametrize("anchor", [5.0, None], ids=["still background", "paper"])
def test_the_basis_with_the_results_maps_is_the_kernels_blend(image, anchor):
    result = warp(image, _scene(anchor), width=WIDTH)
    exact = result.inverse_map(np.float64)
    for handle in range(4):
        basis = live_basis(result, handle)
        assert basis.controls == tuple(j for j, c in enumerate(result.controls) if c.handle == handle)
        got = basis.inverse_lonlat([result.controls[j].moebius for j in basis.controls])
        error = coords.angular_distance(got, _region_of(exact, basis)).max()
        assert error < 1e-4, f"handles[{handle}]: the basis is {error:.2g}° off the kernel's blend"


def test_a_new_arrow_shows_what_the_kernel_computes_for_it(image):
    """Paper mode: turning and pulling an arrow changes the point's map, not the weights; the live sum is then the new result."""
    doc = _scene(None)
    result = warp(image, doc, width=WIDTH)
    point = doc.handles[0]
    tip = offset(point.final, 30.0, 25.0)  # pulled from 17° to 25° and turned up
    turned = point.with_arrow_tip(tip, "east")
    assert turned.scale > 1.3 and abs(turned.rotation) > 20
    after = warp(image, Handles((turned, *doc.handles[1:]), options=doc.options), width=WIDTH, previous=result)
    np.testing.assert_allclose(after.weights, result.weights, atol=1e-9)
    basis = live_basis(result, 0)
    got = basis.inverse_lonlat([turned.moebius()])
    error = coords.angular_distance(got, _region_of(after.inverse_map(np.float64), basis))
    before = coords.angular_distance(_region_of(result.inverse_map(np.float64), basis), _region_of(after.inverse_map(np.float64), basis))
    assert error.max() < 1e-4, f"the live sum is {error.max():.2g}° off the new result"
    assert before.max() > 5.0, "the new arrow should move the result by degrees"


def test_the_region_holds_every_pixel_the_handle_weighs_in_and_wraps_at_the_seam(image):
    result = warp(image, _scene(5.0), width=WIDTH)
    for handle in range(4):
        basis = live_basis(result, handle)
        everywhere = live_basis(result, handle, region_weight=None)
        assert everywhere.fixed.shape[:2] == (WIDTH // 2, WIDTH) and everywhere.origin == (0, 0)
        inside = np.zeros((WIDTH // 2, WIDTH), bool)
        row, col = basis.origin
        height, width = basis.fixed.shape[:2]
        inside[row : row + height, (col + np.arange(width)) % WIDTH] = True
        outside = everywhere.weights.max(axis=-1)[~inside]
        assert outside.max(initial=0.0) <= REGION_WEIGHT
        assert inside.mean() < 0.2, f"handles[{handle}] reaches {inside.mean():.0%} of the image: the box is not tight"
    seam = live_basis(result, 3)
    columns = (seam.origin[1] + np.arange(seam.fixed.shape[1])) % WIDTH
    assert 0 in columns and WIDTH - 1 in columns and len(columns) < WIDTH // 4, "the box around a point on the seam wraps"


def test_the_numpy_path_computes_the_same_basis(image, monkeypatch):
    result = warp(image, _scene(5.0), width=WIDTH)
    compiled = live_basis(result, 2)
    monkeypatch.setattr(_kernels, "available", lambda: False)
    plain = live_basis(result, 2)
    assert plain.origin == compiled.origin
    np.testing.assert_allclose(plain.weights, compiled.weights, atol=1e-5)
    np.testing.assert_allclose(plain.fixed, compiled.fixed, atol=1e-5)


def test_one_map_for_everything_weighs_every_control_the_same(image):
    doc = Handles((PointHandle((20.0, 5.0), (30.0, 0.0), 10.0, 1.5),), options=Options(anchor=None))
    result = warp(image, doc, width=WIDTH)
    assert result.weights is None
    basis = live_basis(result, 0, region_weight=None)
    got = basis.inverse_lonlat([doc.handles[0].moebius()])
    assert coords.angular_distance(got, result.inverse_map(np.float64)).max() < 1e-4


def test_the_packed_texture_keeps_every_channel(image):
    result = warp(image, _scene(5.0), width=WIDTH)
    basis = live_basis(result, 2)  # a cage of three vertices: 3 + 3 + 1 + 3 channels, three layers
    packed = basis.packed()
    height, width = basis.fixed.shape[:2]
    assert packed.dtype == np.float16 and packed.shape == (3 * height, width, 4)
    channels = np.concatenate([packed[:height], packed[height : 2 * height], packed[2 * height :]], axis=-1).astype(np.float32)
    np.testing.assert_allclose(channels[..., :3], basis.fixed, atol=2e-3)
    np.testing.assert_allclose(channels[..., 3:6], basis.weights, atol=1e-3)
    np.testing.assert_allclose(channels[..., 6], basis.share, atol=1e-3)
    np.testing.assert_allclose(channels[..., 7:10], basis.offset, atol=1e-3)
    assert not channels[..., 10:].any()


def test_a_handle_without_a_control_is_refused(image):
    result = warp(image, _scene(5.0), width=WIDTH)
    with pytest.raises(ValueError, match=r"handles\[7\]"):
        live_basis(result, 7)


def test_the_session_sends_the_basis_and_solves_a_drag_without_an_edit():
    from omniwidget.app.session import EditingSession

    sent = []
    session = EditingSession(
        ow.sample_path(), _scene(5.0), preview_width=WIDTH, autosave=False, quality=False, on_message=lambda c, b: sent.append((c, b))
    )
    session.start()
    session.wait()
    session.live_basis_message(2)
    ((header, (buffer,)),) = sent
    assert header["op"] == "live" and header["index"] == 2 and header["controls"] == 3 and header["carry"] is True
    assert header["generation"] == session.status["generation"] and header["size"] == WIDTH
    assert len(buffer) == 3 * header["height"] * header["width"] * 4 * 2  # three layers of RGBA half floats: F, 3 weights, the fill's s and o
    session.live_basis_message(9)  # a handle that is not there: nothing
    assert len(sent) == 1

    # a drag's solve is a preview, not an edit: no undo step, the document unchanged
    before, history = session.handles, dict(session.history)
    moved = session.document.to_dict()
    moved["handles"][0]["target"] = [26.0, 8.0]
    generation = session.status["generation"]
    session.command({"op": "drag", "handles": moved})
    session.wait()
    assert session.status["generation"] > generation and session.status["state"] == "idle"
    assert session.handles == before and session.history == history
    assert session.preview_result.handles.handles[0].final == (26.0, 8.0)
    assert session.outputs[0][0] == pytest.approx([26.0, 8.0])
