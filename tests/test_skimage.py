"""scikit-image takes a warp's inverse map as it is: ``skimage.transform.warp`` reproduces ``ow.warp``'s image."""

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import DEMO_HANDLES
from tests import requires

skimage_transform = requires.module("skimage.transform")


@pytest.fixture(scope="module")
def demo():
    image = ow.sample_image()
    return image, ow.warp(image, ow.Handles.from_dict(DEMO_HANDLES), warn=False)


def _away_from_seam_and_poles(result, margin=1.0):
    m = result.inverse_map(np.float64)
    return (np.abs(m[..., 0]) < 180 - margin) & (np.abs(m[..., 1]) < 90 - 2 * margin)


def test_skimage_warp_with_the_results_inverse_map_gives_the_same_image(demo):
    image, result = demo
    theirs = skimage_transform.warp(image, result.skimage_inverse_map(image.shape[2]), order=1, mode="wrap", preserve_range=True)
    assert theirs.shape == result.image.shape
    diff = np.abs(np.rint(theirs) - result.image.astype(np.float64)).max(axis=-1)
    away = _away_from_seam_and_poles(result)
    assert away.mean() > 0.95  # nearly the whole image is compared
    assert diff[away].max() <= 1.0, diff[away].max()  # within one grey level (OpenCV interpolates in 1/32 px steps)
    assert np.mean(diff[away] > 0) < 0.05


def test_a_grey_image_takes_the_two_dimensional_form(demo):
    image, result = demo
    grey = image[..., 1]
    coordinates = result.skimage_inverse_map()
    assert coordinates.shape == (2, *result.image.shape[:2])
    theirs = skimage_transform.warp(grey, coordinates, order=1, mode="wrap", preserve_range=True)
    ours = ow.warp(grey, result.handles, warn=False).image
    away = _away_from_seam_and_poles(result)
    assert np.abs(np.rint(theirs) - ours.astype(np.float64))[away].max() <= 1.0


def test_the_map_is_the_inverse_map_in_pixels(demo):
    _, result = demo
    rc = result.skimage_inverse_map()
    lonlat = result.inverse_map(np.float64)
    width = result.source_width
    np.testing.assert_allclose(rc[1], (lonlat[..., 0] + 180) * width / 360 - 0.5, atol=1e-9)
    np.testing.assert_allclose(rc[0], (90 - lonlat[..., 1]) * width / 360 - 0.5, atol=1e-9)
    with pytest.raises(ValueError, match="channels"):
        result.skimage_inverse_map(0)
