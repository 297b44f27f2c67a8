"""The perspective camera (omniwidget.raster.perspective): ``ow.view`` and ``omniwidget view``.

The geometry is checked on generated panoramas: small bright discs painted on the sphere at
directions chosen in the camera's own frame (``forward + a east + b north``) must appear,
in the rendered still, at ``(cx + f a, cy - f b)``, the camera model's closed form, within
1 px (the blob's intensity centroid).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import main
from omniwidget.evaluate import baselines
from omniwidget.io.images import read_image, write_image
from omniwidget.raster import perspective as camera
from omniwidget.sphere import coords
from tests.test_js import node_command

#: The discs' angular radius, degrees: about 4 px of the 2048 px panorama and of the stills.
RADIUS = 0.7


def _markers_panorama(directions: np.ndarray, width: int = 2048) -> np.ndarray:
    """A black panorama with a white disc of RADIUS degrees (on the sphere) round each direction (unit vectors, (n, 3))."""
    lon, lat = coords.grid_lonlat(width)
    grid = coords.lonlat_to_xyz(np.stack(np.meshgrid(lon, lat), axis=-1))
    image = np.zeros((width // 2, width), np.uint8)
    cos_r = math.cos(math.radians(RADIUS))
    for d in directions:
        image[grid @ d > cos_r] = 255
    return np.repeat(image[..., None], 3, axis=-1)


def _frame(yaw: float, pitch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera's forward, east and north, written out here from the formulas (not from coords)."""
    lon, lat = math.radians(yaw), math.radians(pitch)
    forward = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    north = np.array([-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)])
    return forward, east, north


def _centroids(image: np.ndarray, expected: np.ndarray, window: int = 12) -> np.ndarray:
    """The intensity centroid (x, y) of the blob near each expected pixel."""
    gray = image[..., 0].astype(float)
    found = []
    for x, y in expected:
        x0, y0 = round(x), round(y)
        ys, xs = np.mgrid[y0 - window : y0 + window + 1, x0 - window : x0 + window + 1]
        w = gray[ys, xs]
        assert w.sum() > 0, (x, y)
        found.append([np.sum(w * xs) / w.sum(), np.sum(w * ys) / w.sum()])
    return np.array(found)


CAMERAS = [
    # yaw, pitch, fov, width, height
    (0.0, 0.0, 90.0, 640, 360),
    (30.0, 10.0, 100.0, 641, 401),
    (180.0, -20.0, 70.0, 500, 500),  # across the ±180° seam
    (-135.0, 60.0, 110.0, 720, 480),
    (45.0, 90.0, 90.0, 400, 300),  # straight up: east and north follow the yaw
    (-60.0, -90.0, 60.0, 300, 400),  # straight down
]


@pytest.mark.parametrize(("yaw", "pitch", "fov", "width", "height"), CAMERAS)
def test_markers_land_where_the_camera_model_says(yaw, pitch, fov, width, height):
    forward, east, north = _frame(yaw, pitch)
    focal = width / (2 * math.tan(math.radians(fov) / 2))
    cx, cy = (width - 1) / 2, (height - 1) / 2
    # offsets on the image plane (units of the focal length), as fractions of the half width and height: the
    # centre, right, up, lower left, towards the upper right corner (where the view stretches most), left and up
    fractions = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.6], [-0.6, -0.5], [0.8, 0.7], [-0.3, 0.5]])
    planar = fractions * [cx / focal, cy / focal]
    rays = forward + planar[:, :1] * east + planar[:, 1:] * north
    directions = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    expected = np.stack([cx + focal * planar[:, 0], cy - focal * planar[:, 1]], axis=-1)

    still = ow.view(_markers_panorama(directions), yaw=yaw, pitch=pitch, fov=fov, width=width, height=height)
    assert still.image.shape == (height, width, 3) and still.image.dtype == np.uint8
    found = _centroids(still.image, expected)
    error = np.hypot(*(found - expected).T)
    print(f"\nyaw {yaw:g} pitch {pitch:g} fov {fov:g}: the markers {error.max():.2f} px from the camera model at most")
    assert error.max() < 1.0, (found, expected)
    # the view's own projection says the same, and the rays it rendered agree with it
    np.testing.assert_allclose(still.project(coords.xyz_to_lonlat(directions)), expected, atol=1e-9)
    if width % 2 and height % 2:
        assert coords.angular_distance(still.lonlat[height // 2, width // 2], (coords.wrap_lon(yaw), pitch)) < 1e-9


def test_east_is_right_and_north_is_up():
    """On the horizon, a marker 20° east of the view's centre is right of it and one 15° north is above it, at f tan(angle)."""
    directions = coords.lonlat_to_xyz([[20.0, 0.0], [0.0, 15.0]])
    still = ow.view(_markers_panorama(directions), yaw=0.0, pitch=0.0, fov=90.0, width=401, height=301)
    focal = 401 / 2
    found = _centroids(still.image, [[200 + focal * math.tan(math.radians(20)), 150], [200, 150 - focal * math.tan(math.radians(15))]])
    np.testing.assert_allclose(found, [[200 + focal * math.tan(math.radians(20)), 150], [200, 150 - focal * math.tan(math.radians(15))]], atol=1.0)


def test_view_is_the_one_perspective_camera():
    image = _markers_panorama(coords.lonlat_to_xyz([[10.0, 5.0]]), 256)
    assert baselines.perspective is camera.perspective and baselines.PerspectiveView is camera.PerspectiveView
    a = ow.view(image, yaw=370.0, pitch=5.0, fov=60.0, width=64, height=48)  # the yaw wrapped: 10°
    b = baselines.perspective(image, (10.0, 5.0), 60.0, 64, 48)
    assert a.center == (10.0, 5.0) and np.array_equal(a.image, b.image) and np.array_equal(a.lonlat, b.lonlat)
    assert ow.view(image, width=320).image.shape == (180, 320, 3)  # the default height: 16:9
    assert ow.view(image, width=1, height=None).image.shape == (1, 1, 3)


def test_view_refuses_bad_cameras_by_name():
    image = np.zeros((32, 64, 3), np.uint8)
    for pitch in (90.5, -95.0):
        with pytest.raises(ValueError, match=r"^pitch .*: the latitude of the view's centre must be within \[-90, 90\] degrees"):
            ow.view(image, pitch=pitch)
    for fov in (0.0, 180.0, -10.0, 200):
        with pytest.raises(ValueError, match=r"^fov .*: the horizontal field of view must be more than 0 and less than 180 degrees"):
            ow.view(image, fov=fov)
    for name in ("yaw", "pitch", "fov"):
        for bad in (float("nan"), float("inf"), "30", True, None):
            with pytest.raises(ValueError, match=rf"^{name} .*: must be a finite number of degrees"):
                ow.view(image, **{name: bad})
    with pytest.raises(ValueError, match="width must be a positive integer, got 0"):
        ow.view(image, width=0)
    with pytest.raises(ValueError, match="height must be a positive integer, got 2.5"):
        ow.view(image, height=2.5)
    with pytest.raises(ValueError, match="order must be one of"):
        ow.view(image, order="cubic")
    with pytest.raises(ow.ImageError, match="twice as wide as high"):
        ow.view(image[:, :40])


# --- omniwidget view --------------------------------------------------------------------


@pytest.fixture
def pano(tmp_path):
    directions = coords.lonlat_to_xyz([[30.0, 10.0], [60.0, 0.0]])
    image = _markers_panorama(directions, 512)
    image[..., 1] = np.linspace(0, 200, 512, dtype=np.uint8)[None, :]  # a gradient: east is told from west
    write_image(tmp_path / "in.png", image)
    return tmp_path


def test_view_writes_the_still_of_ow_view(pano, capsys):
    code = main(["view", str(pano / "in.png"), "-o", str(pano / "still.png"), "--yaw", "390", "--pitch", "10", "--fov", "80", "--width", "320", "--height", "200"])
    err = capsys.readouterr().err
    assert code == 0 and err.count("\n") == 1, err
    assert "wrote" in err and "(320 x 200)" in err and "yaw 30°, pitch 10°, 80° across" in err, err
    still = read_image(pano / "still.png")
    expected = ow.view(read_image(pano / "in.png"), yaw=30.0, pitch=10.0, fov=80.0, width=320, height=200).image
    assert np.array_equal(still, expected)
    assert still[99:101, 159:161, 0].max() > 200 and still[:90, :, 0].max() < 100  # the marker at the centre, nothing above it
    assert sorted(p.name for p in pano.iterdir()) == ["in.png", "still.png"]  # no temporary file left
    assert main(["view", str(pano / "in.png"), "-o", str(pano / "q.jpg"), "-q"]) == 0
    assert capsys.readouterr().err == "" and read_image(pano / "q.jpg").shape == (720, 1280, 3)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--pitch", "95"], "--pitch 95: the latitude of the view's centre must be within [-90, 90] degrees"),
        (["--pitch", "-90.5"], "--pitch -90.5: the latitude"),
        (["--fov", "180"], "--fov 180: the horizontal field of view must be more than 0 and less than 180 degrees"),
        (["--fov", "0"], "--fov 0: the horizontal field of view"),
        (["--yaw", "nan"], "--yaw nan: must be a finite number of degrees"),
        (["--fov", "inf"], "--fov inf: must be a finite number of degrees"),
        (["--width", "0"], "--width 0: at least one pixel"),
        (["--height", "-3"], "--height -3: at least one pixel"),
    ],
)
def test_view_refuses_a_bad_camera_in_one_line(pano, capsys, options, message):
    listing = sorted(p.name for p in pano.iterdir())
    code = main(["view", str(pano / "in.png"), "-o", str(pano / "still.png"), *options])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("omniwidget view: error: ") and message in err, err
    assert sorted(p.name for p in pano.iterdir()) == listing  # nothing written


def test_view_refuses_bad_files_in_one_line(pano, capsys):
    write_image(pano / "wide.png", np.zeros((10, 30, 3), np.uint8))
    listing = sorted(p.name for p in pano.iterdir())
    for argv, message in (
        (["missing.png", "-o", "still.png"], "cannot read"),
        (["wide.png", "-o", "still.png"], "twice as wide as high"),
        (["in.png", "-o", "still.txt"], "the output image must end in"),
        (["in.png", "-o", "in.png"], "would overwrite the input"),
        (["in.png", "-o", "no/such/folder/still.png"], "does not exist"),
    ):
        code = main(["view", str(pano / argv[0]), *argv[1:-1], str(pano / argv[-1])])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err and message in err, (argv, err)
        assert sorted(p.name for p in pano.iterdir()) == listing
    with pytest.raises(SystemExit) as info:  # argparse's own: not a number
        main(["view", str(pano / "in.png"), "-o", str(pano / "still.png"), "--yaw", "east"])
    assert info.value.code == 2 and capsys.readouterr().err.count("\n") == 1


# --- the editor's camera (static/look.js) is this one ------------------------------------


def test_the_editors_look_around_camera_is_this_one():
    """look.js's rays (the editor's look-around view) are the rays ow.view renders, pixel for pixel, to 1e-9 degrees."""
    import json
    import subprocess
    from pathlib import Path

    node = node_command()  # skipped without node, failed when the browser tests must run
    look = (Path(__file__).resolve().parents[1] / "omniwidget" / "widget" / "static" / "look.js").as_uri()
    cameras = [(30.0, 10.0, 100.0, 41, 31), (-179.5, -20.0, 70.0, 40, 30), (45.0, 90.0, 60.0, 33, 20), (120.0, -90.0, 120.0, 20, 33)]
    script = (
        f"import({json.dumps(look)}).then((l) => console.log(JSON.stringify({json.dumps(cameras)}.map(([yaw, pitch, fov, w, h]) =>"
        " Array.from({length: h}, (_, y) => Array.from({length: w}, (_, x) => l.lonlatAt({yaw, pitch, fov}, w, h, x, y)))))))"
    )
    run = subprocess.run([node, "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    image = np.zeros((8, 16, 3), np.uint8)
    for (yaw, pitch, fov, width, height), rays in zip(cameras, json.loads(run.stdout), strict=True):
        python = ow.view(image, yaw=yaw, pitch=pitch, fov=fov, width=width, height=height).lonlat
        assert coords.angular_distance(np.array(rays), python).max() < 1e-9, (yaw, pitch, fov)
