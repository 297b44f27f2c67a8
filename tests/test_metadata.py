"""A 360° photo stays a 360° photo: its metadata kept and made true, a part of a sphere put in its place, the pose written.

exiftool (Debian's ``libimage-exiftool-perl``; .ci/run installs it) is the independent
reader: the test files are tagged with it, and every output is read back with it. Without
it the tests that need it are skipped, except when ``OMNIWIDGET_REQUIRE_EXIFTOOL`` is set.
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import subprocess

import cv2
import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import main
from omniwidget.detect.level import tilt_rotation
from omniwidget.document.handles import Handles, Options
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io import large, metadata
from omniwidget.io.images import encode_image, read_image, write_image, write_image_strips
from omniwidget.raster import strips
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

EXIFTOOL = shutil.which("exiftool")
needs_exiftool = pytest.mark.skipif(
    EXIFTOOL is None and not os.environ.get("OMNIWIDGET_REQUIRE_EXIFTOOL"), reason="exiftool is not installed (apt-get install libimage-exiftool-perl)"
)

#: What the camera wrote, as exiftool reads it back.
CAMERA = {
    "Make": "RICOH",
    "Model": "RICOH THETA Z1",
    "DateTimeOriginal": "2024:05:06 07:08:09",
    "GPSLatitude": 48.8584,
    "GPSLongitude": 2.2945,
}


@functools.cache
def _icc() -> bytes:
    """An sRGB profile made by Pillow's LittleCMS (made once: its header holds the time it was made)."""
    from PIL import ImageCms

    return ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()


def _exiftool(*args: str) -> None:
    subprocess.run([EXIFTOOL or "exiftool", "-q", "-q", "-overwrite_original", *args], check=True)


def _tag(path, *, width: int, height: int, orientation: int = 6, gpano: bool = True, crop=None, pose=(90.0, 3.5, -1.25)) -> bytes:
    """Tag a file as a camera would: EXIF (GPS, date, camera, orientation), an ICC profile, GPano; returns the profile."""
    icc = path.parent / "profile.icc"
    icc.write_bytes(_icc())
    args = [
        f"-Orientation#={orientation}",
        f"-Make={CAMERA['Make']}",
        f"-Model={CAMERA['Model']}",
        f"-DateTimeOriginal={CAMERA['DateTimeOriginal']}",
        f"-GPSLatitude={CAMERA['GPSLatitude']}",
        "-GPSLatitudeRef=N",
        f"-GPSLongitude={CAMERA['GPSLongitude']}",
        "-GPSLongitudeRef=E",
        f"-ExifImageWidth={width}",
        f"-ExifImageHeight={height}",
        "-XMP-dc:Title=the courtyard",
        f"-ICC_Profile<={icc}",
    ]
    if gpano:
        full_w, full_h, crop_w, crop_h, left, top = crop or (width, height, width, height, 0, 0)
        args += [
            "-XMP-GPano:ProjectionType=equirectangular",
            "-XMP-GPano:UsePanoramaViewer=True",
            f"-XMP-GPano:FullPanoWidthPixels={full_w}",
            f"-XMP-GPano:FullPanoHeightPixels={full_h}",
            f"-XMP-GPano:CroppedAreaImageWidthPixels={crop_w}",
            f"-XMP-GPano:CroppedAreaImageHeightPixels={crop_h}",
            f"-XMP-GPano:CroppedAreaLeftPixels={left}",
            f"-XMP-GPano:CroppedAreaTopPixels={top}",
        ]
        if pose is not None:
            args += [f"-XMP-GPano:PoseHeadingDegrees={pose[0]}", f"-XMP-GPano:PosePitchDegrees={pose[1]}", f"-XMP-GPano:PoseRollDegrees={pose[2]}"]
    _exiftool(*args, str(path))
    return icc.read_bytes()


def _read_tags(path) -> dict:
    out = subprocess.run([EXIFTOOL or "exiftool", "-j", "-n", "-G1", "-a", "-warning", "-all", str(path)], capture_output=True, text=True, check=True)
    (tags,) = json.loads(out.stdout)
    return tags


def _icc_of(path) -> bytes:
    return subprocess.run([EXIFTOOL or "exiftool", "-b", "-ICC_Profile", str(path)], capture_output=True, check=True).stdout


def _check_output(path, icc: bytes, width: int, *, pitch: float | None, roll: float | None, heading: float | None = 90.0) -> dict:
    """What every output must carry: GPano of a whole ``width``-wide sphere, the camera's EXIF, orientation 1, the ICC profile byte for byte."""
    tags = _read_tags(path)
    assert "ExifTool:Warning" not in tags, tags.get("ExifTool:Warning")
    g = {k.split(":", 1)[1]: v for k, v in tags.items() if k.startswith("XMP-GPano:")}
    assert g["ProjectionType"] == "equirectangular"
    assert (g["FullPanoWidthPixels"], g["FullPanoHeightPixels"]) == (width, width // 2)
    assert (g["CroppedAreaImageWidthPixels"], g["CroppedAreaImageHeightPixels"], g["CroppedAreaLeftPixels"], g["CroppedAreaTopPixels"]) == (
        width,
        width // 2,
        0,
        0,
    )
    for name, want in (("PoseHeadingDegrees", heading), ("PosePitchDegrees", pitch), ("PoseRollDegrees", roll)):
        if want is None:
            assert name not in g
        else:
            assert g[name] == pytest.approx(want, abs=1e-3), name
    assert tags["IFD0:Orientation"] == 1
    assert (tags["IFD0:Make"], tags["IFD0:Model"], tags["ExifIFD:DateTimeOriginal"]) == (CAMERA["Make"], CAMERA["Model"], CAMERA["DateTimeOriginal"])
    assert tags["GPS:GPSLatitude"] == pytest.approx(CAMERA["GPSLatitude"], abs=1e-4)
    assert tags["GPS:GPSLongitude"] == pytest.approx(CAMERA["GPSLongitude"], abs=1e-4)
    assert (tags["ExifIFD:ExifImageWidth"], tags["ExifIFD:ExifImageHeight"]) == (width, width // 2)
    assert tags["XMP-dc:Title"] == "the courtyard"  # the input's other XMP kept
    assert _icc_of(path) == icc
    return tags


def _stored(shown: np.ndarray) -> np.ndarray:
    """The pixels a camera stores for orientation 6 (shown turned a quarter clockwise)."""
    return np.ascontiguousarray(np.rot90(shown, 1))


@pytest.fixture
def tagged(tmp_path):
    """A 512 x 256 JPEG panorama stored turned (orientation 6) with GPano, GPS, date, camera and an ICC profile; and handles."""
    shown = synthetic_room(512, pitch=4.0, roll=-3.0, seed=1).image
    path = tmp_path / "room.jpg"
    write_image(path, _stored(shown))
    icc = _tag(path, width=512, height=256)
    plain = tmp_path / "plain.jpg"
    write_image(plain, shown)
    doc = Handles((), Options(up=(20.0, 80.0)))
    (tmp_path / "level.json").write_text(doc.to_json())
    (tmp_path / "point.json").write_text(
        json.dumps({"format": "omniwidget.handles", "version": 1, "handles": [{"kind": "point", "position": [10, 20], "target": [12, 18]}]})
    )
    return tmp_path, path, icc, shown


# --- the pixels are those written without metadata -------------------------------------------


@pytest.mark.parametrize("suffix", [".jpg", ".png", ".webp"])
def test_metadata_is_added_to_the_encoded_bytes_and_the_pixels_are_those_written_without_it(tmp_path, suffix):
    image = synthetic_room(256, seed=3).image
    source = tmp_path / "source.jpg"
    write_image(source, image)
    meta = metadata.output_metadata(metadata.read_metadata(source), 256, 128)
    bare = encode_image(tmp_path / f"x{suffix}", image)
    dressed = encode_image(tmp_path / f"x{suffix}", image, meta)
    assert len(dressed) > len(bare)
    a = cv2.imdecode(np.frombuffer(bare, np.uint8), cv2.IMREAD_UNCHANGED)
    b = cv2.imdecode(np.frombuffer(dressed, np.uint8), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(a, b)
    if suffix == ".jpg":  # the entropy-coded data itself is the same bytes
        assert bare[bare.index(b"\xff\xda") :] == dressed[dressed.index(b"\xff\xda") :]
    got = metadata.read_metadata(dressed).gpano
    assert got is not None and (got.full_width, got.full_height, got.is_full) == (256, 128, True)


def test_orientation_is_read_by_pillow_and_malformed_exif_reads_as_1():
    good = b"MM\x00*\x00\x00\x00\x08\x00\x01\x01\x12\x00\x03\x00\x00\x00\x01\x00\x06\x00\x00\x00\x00\x00\x00"
    assert metadata.orientation(good) == 6
    assert metadata.orientation(b"Exif\x00\x00" + good) == 6
    assert metadata.orientation(good[:12]) == 1
    assert metadata.orientation(b"nonsense") == 1


@needs_exiftool
def test_the_exif_is_patched_in_place_and_its_thumbnail_link_cut(tmp_path):
    path = tmp_path / "a.jpg"
    write_image(path, synthetic_room(128, seed=3).image)
    _tag(path, width=128, height=64)
    exif = metadata.read_metadata(path).exif
    patched = metadata.output_metadata(metadata.Metadata(exif=exif), 300, 150).exif
    assert patched is not None and len(patched) == len(exif)
    differ = np.flatnonzero(np.frombuffer(exif, np.uint8) != np.frombuffer(patched, np.uint8))
    assert 0 < len(differ) <= 10  # orientation 2 bytes, the sizes up to 4 each: nothing else moved
    assert metadata.orientation(patched) == 1


# --- every output path, read back with exiftool ----------------------------------------------


@needs_exiftool
def test_warp_keeps_the_metadata_and_makes_it_true(tagged, capsys):
    folder, path, icc, shown = tagged
    assert main(["warp", str(path), "-H", str(folder / "point.json"), "-o", str(folder / "out.jpg"), "--width", "384"]) == 0
    _check_output(folder / "out.jpg", icc, 384, pitch=3.5, roll=-1.25)  # not levelled: the camera's pose kept
    out = read_image(folder / "out.jpg")
    assert out.shape == (192, 384, 3)  # written as shown (the input turned by its orientation 6)
    assert main(["warp", str(path), "-H", str(folder / "level.json"), "-o", str(folder / "levelled.png")]) == 0
    _check_output(folder / "levelled.png", icc, 512, pitch=0.0, roll=0.0)  # options.up: levelled, the heading kept
    assert main(["warp", str(path), "-H", str(folder / "point.json"), "-o", str(folder / "out.webp")]) == 0
    _check_output(folder / "out.webp", icc, 512, pitch=3.5, roll=-1.25)
    assert main(["warp", str(path), "-H", str(folder / "point.json"), "-o", str(folder / "out.tif")]) == 0
    tags = _read_tags(folder / "out.tif")  # TIFF: the XMP and the ICC profile (no EXIF block), the pixels OpenCV's
    assert (tags["XMP-GPano:FullPanoWidthPixels"], tags["XMP-GPano:PosePitchDegrees"], tags["XMP-dc:Title"]) == (512, 3.5, "the courtyard")
    assert _icc_of(folder / "out.tif") == icc
    assert main(["warp", str(path), "-H", str(folder / "point.json"), "-o", str(folder / "out.png")]) == 0
    assert np.array_equal(read_image(folder / "out.tif"), read_image(folder / "out.png"))  # both lossless: the same pixels


@needs_exiftool
def test_an_input_without_gpano_gets_it_unless_no_gpano(tagged, capsys):
    folder, _, icc, shown = tagged
    plain = folder / "plain.jpg"
    _tag(plain, width=512, height=256, orientation=1, gpano=False)
    assert main(["warp", str(plain), "-H", str(folder / "point.json"), "-o", str(folder / "a.jpg")]) == 0
    _check_output(folder / "a.jpg", icc, 512, pitch=None, roll=None, heading=None)
    assert main(["warp", str(plain), "-H", str(folder / "point.json"), "-o", str(folder / "b.jpg"), "--no-gpano"]) == 0
    tags = _read_tags(folder / "b.jpg")
    assert not [k for k in tags if k.startswith("XMP-GPano:")]
    assert tags["XMP-dc:Title"] == "the courtyard" and tags["GPS:GPSLatitude"] == pytest.approx(CAMERA["GPSLatitude"], abs=1e-4)
    assert _icc_of(folder / "b.jpg") == icc


@needs_exiftool
@pytest.mark.parametrize("suffix", [".jpg", ".png", ".tif"])
def test_warp_in_strips_keeps_the_metadata(tagged, monkeypatch, capsys, suffix):
    folder, path, icc, _ = tagged
    monkeypatch.setattr(strips, "STREAM_WIDTH", 256)  # made in strips
    monkeypatch.setattr(strips, "MAP_WIDTH", 256)
    out = folder / f"strips{suffix}"
    assert main(["warp", str(path), "-H", str(folder / "level.json"), "-o", str(out)]) == 0
    assert "in strips" in capsys.readouterr().err
    if suffix == ".tif":  # TIFF carries the XMP and the ICC profile (no EXIF block)
        tags = _read_tags(out)
        assert (tags["XMP-GPano:FullPanoWidthPixels"], tags["XMP-GPano:PosePitchDegrees"], tags["XMP-dc:Title"]) == (512, 0, "the courtyard")
        assert _icc_of(out) == icc
    else:
        _check_output(out, icc, 512, pitch=0.0, roll=0.0)
    whole = folder / f"whole{suffix}"
    monkeypatch.setattr(strips, "STREAM_WIDTH", 16384)
    assert main(["warp", str(path), "-H", str(folder / "level.json"), "-o", str(whole)]) == 0
    if suffix != ".jpg":  # lossless: the strips' pixels are the whole warp's
        assert np.abs(read_image(out).astype(int) - read_image(whole)).max() <= 1


@needs_exiftool
def test_frames_each_keep_their_own_metadata(tagged, capsys):
    folder, path, icc, shown = tagged
    frames = folder / "frames"
    frames.mkdir()
    for k in range(3):
        write_image(frames / f"f{k}.jpg", _stored(shown))
        _tag(frames / f"f{k}.jpg", width=512, height=256, pose=(10.0 * k, 1.0, 2.0))
    inputs = [str(frames / f"f{k}.jpg") for k in range(3)]
    assert main(["warp", *inputs, "-H", str(folder / "point.json"), "-o", str(folder / "out"), "--width", "256"]) == 0
    for k in range(3):
        _check_output(folder / "out" / f"f{k}.jpg", icc, 256, pitch=1.0, roll=2.0, heading=10.0 * k)


@needs_exiftool
def test_level_writes_the_pose_that_is_now_true(tagged, capsys):
    folder, path, icc, _ = tagged
    assert main(["level", str(path), "-o", str(folder / "level.jpg")]) == 0
    _check_output(folder / "level.jpg", icc, 512, pitch=0.0, roll=0.0)


@pytest.mark.slow  # the structure found and rectified: about 5 s
@needs_exiftool
def test_straighten_keeps_the_metadata_and_writes_it_levelled(tagged, capsys):
    folder, path, icc, _ = tagged
    assert main(["straighten", str(path), "-o", str(folder / "straight.jpg")]) == 0
    _check_output(folder / "straight.jpg", icc, 512, pitch=0.0, roll=0.0)
    assert main(["straighten", str(path), "-o", str(folder / "kept.jpg"), "--no-level"]) == 0
    _check_output(folder / "kept.jpg", icc, 512, pitch=3.5, roll=-1.25)


@needs_exiftool
def test_the_editor_saves_the_metadata(tagged, monkeypatch):
    from omniwidget.app.session import EditingSession

    folder, path, icc, _ = tagged
    doc = Handles.from_json((folder / "level.json").read_text())
    session = EditingSession(path, doc, autosave=False, quality=False)
    written = session.save_image(folder / "saved.jpg")
    _check_output(written, icc, 512, pitch=0.0, roll=0.0)
    session.save_image(folder / "bare.png", gpano=False)  # the input's GPano is still brought up to date
    _check_output(folder / "bare.png", icc, 512, pitch=0.0, roll=0.0)
    monkeypatch.setattr(strips, "STREAM_WIDTH", 256)  # Save image in strips, read from disk a patch at a time
    monkeypatch.setattr(strips, "MAP_WIDTH", 256)
    monkeypatch.setenv(large.STREAM_VARIABLE, "1")
    plain = folder / "plain.jpg"  # stored as shown: a panorama read from disk must be 2:1 as stored (app/strips.py)
    _tag(plain, width=512, height=256, orientation=1)
    written = EditingSession(plain, doc, autosave=False, quality=False).save_image(folder / "strips.jpg")
    _check_output(written, icc, 512, pitch=0.0, roll=0.0)


def test_write_image_strips_writes_png_chunks_pillow_reads(tmp_path):
    image = synthetic_room(256, seed=5).image
    meta = metadata.Metadata(icc=_icc(), xmp=metadata.replace_xmp(None, metadata.GPano.full(256, 128)))
    write_image_strips(tmp_path / "a.png", image.shape, image.dtype, [image[:50], image[50:]], meta=meta)
    assert np.array_equal(read_image(tmp_path / "a.png"), image)
    got = metadata.read_metadata(tmp_path / "a.png")
    assert got.icc == meta.icc and got.gpano == metadata.GPano.full(256, 128)


# --- a part of a sphere put in its place -------------------------------------------------------

#: The full panorama's size, and the sweep's rows: 360 x 120° starting 20° below the zenith (not centred: --fit pad
#: would put it 10° too low).
FULL_W, FULL_H, TOP, ROWS = 1080, 540, 60, 360


def _marked_full() -> tuple[np.ndarray, list[tuple[float, float]]]:
    """A full panorama with bright markers at known places (some near the sweep's top and bottom edges)."""
    image = synthetic_room(FULL_W, seed=7).image // 2
    places = [(30.0, 45.0), (-120.0, -30.0), (170.0, 0.0), (-60.0, 60.0), (90.0, -45.0)]
    for lon, lat in places:
        x, y = coords.lonlat_to_px(np.array([lon, lat]), FULL_W)
        cv2.circle(image, (round(float(x) * 16), round(float(y) * 16)), 3 * 16, (255, 255, 255), -1, cv2.LINE_AA, shift=4)
    return image, places


def _centroids(image: np.ndarray, places, width: int) -> np.ndarray:
    """Where each marker is found (the centroid of the bright pixels near where it should be), pixels."""
    grey = image[..., :3].astype(np.float64).mean(axis=-1)
    found = []
    for lon, lat in places:
        x, y = (float(v) for v in coords.lonlat_to_px(np.array([lon, lat]), width))
        r0, c0 = max(0, round(y) - 20), max(0, round(x) - 20)
        patch = grey[r0 : round(y) + 21, c0 : round(x) + 21]
        weights = np.clip(patch - 180, 0, None)
        assert weights.sum() > 0, f"the marker at {lon}, {lat} is not there"
        rows, cols = np.indices(patch.shape)
        found.append(((cols * weights).sum() / weights.sum() + c0, (rows * weights).sum() / weights.sum() + r0))
    return np.array(found)


@needs_exiftool
def test_a_partial_panorama_lands_where_its_gpano_says(tmp_path, capsys):
    from omniwidget.app.session import EditingSession

    full, places = _marked_full()
    write_image(tmp_path / "full.png", full)
    sweep = tmp_path / "sweep.png"
    write_image(sweep, full[TOP : TOP + ROWS])
    _tag(sweep, width=FULL_W, height=ROWS, orientation=1, crop=(FULL_W, FULL_H, FULL_W, ROWS, 0, TOP), pose=None)
    want = _centroids(full, places, FULL_W)
    placed = ow.read_image(sweep)
    assert placed.shape == full.shape
    assert np.abs(_centroids(placed, places, FULL_W) - want).max() <= 1.0
    assert not placed[:TOP].any() and not placed[TOP + ROWS :].any()
    assert ow.read_image(sweep, place=False).shape == (ROWS, FULL_W, 3)  # as the file holds it, on request
    # ... as to_equirectangular does given the XMP, whatever fit says
    gpano = metadata.read_metadata(sweep).gpano
    assert np.array_equal(ow.to_equirectangular(full[TOP : TOP + ROWS], "pad", gpano=gpano), placed)
    padded = ow.to_equirectangular(full[TOP : TOP + ROWS], "pad")  # without it: centred, 30 rows too low
    assert np.array_equal(padded[TOP + 30 : TOP + 30 + ROWS], full[TOP : TOP + ROWS])
    # the command line: an identity warp puts it on the sphere; its output says it is whole
    (tmp_path / "none.json").write_text(Handles(()).to_json())
    assert main(["warp", str(sweep), "-H", str(tmp_path / "none.json"), "-o", str(tmp_path / "out.png")]) == 0
    assert np.abs(_centroids(read_image(tmp_path / "out.png"), places, FULL_W) - want).max() <= 1.0
    tags = _read_tags(tmp_path / "out.png")
    assert (tags["XMP-GPano:CroppedAreaImageHeightPixels"], tags["XMP-GPano:CroppedAreaTopPixels"]) == (FULL_H, 0)
    # the editor
    session = EditingSession(sweep, autosave=False, quality=False)
    assert np.abs(_centroids(np.asarray(session.image), places, FULL_W) - want).max() <= 1.0


@needs_exiftool
def test_a_resized_partial_panorama_and_one_past_the_seam_are_placed(tmp_path):
    full, places = _marked_full()
    # 270° wide from lon -45.3 across the seam, rows as above, the file then halved: the XMP still in the full size's pixels
    left, width = 404, 810
    part = np.roll(full, -left, axis=1)[TOP : TOP + ROWS, :width]
    path = tmp_path / "part.png"
    write_image(path, cv2.resize(part, (width // 2, ROWS // 2), interpolation=cv2.INTER_AREA))
    _tag(path, width=width // 2, height=ROWS // 2, orientation=1, crop=(FULL_W, FULL_H, width, ROWS, left, TOP), pose=None)
    placed = ow.read_image(path)
    assert placed.shape == (FULL_H // 2, FULL_W // 2, 3)
    inside = [p for p in places if (p[0] + 180 - left / 3) % 360 < width / 3]
    half = cv2.resize(full, (FULL_W // 2, FULL_H // 2), interpolation=cv2.INTER_AREA)
    assert np.abs(_centroids(placed, inside, FULL_W // 2) - _centroids(half, inside, FULL_W // 2)).max() <= 1.0


def test_without_gpano_the_fit_is_as_before(tmp_path):
    band = np.ones((300, 1000, 3), np.uint8)
    write_image(tmp_path / "band.png", band)
    assert ow.read_image(tmp_path / "band.png").shape == (300, 1000, 3)
    assert ow.read_panorama(tmp_path / "band.png", "pad").shape == (500, 1000, 3)
    # tags that place nothing (a sphere that is not 2:1) are read as if absent
    bad = metadata.Metadata(xmp=metadata.replace_xmp(None, metadata.GPano(1000, 700, 1000, 300, 0, 100)))
    (tmp_path / "bad.png").write_bytes(encode_image(tmp_path / "bad.png", band, bad))
    assert metadata.read_metadata(tmp_path / "bad.png").gpano == metadata.GPano(1000, 700, 1000, 300, 0, 100)
    assert ow.read_image(tmp_path / "bad.png").shape == (300, 1000, 3)
    assert ow.read_panorama(tmp_path / "bad.png", "pad").shape == (500, 1000, 3)


# --- levelling without resampling ---------------------------------------------------------------


@needs_exiftool
def test_pose_only_writes_the_pose_and_copies_the_pixels(tmp_path, capsys):
    """The pose read back by exiftool; the file's bytes but its XMP the input's; a viewer's turn by it matches level's pixels."""
    image = synthetic_room(1024, pitch=4.0, roll=-3.0, seed=1).image
    source = tmp_path / "tilted.png"
    write_image(source, image)
    _tag(source, width=1024, height=512, orientation=1, gpano=False)
    assert main(["level", str(source), "-o", str(tmp_path / "posed.png"), "--pose-only"]) == 0
    assert main(["level", str(source), "-o", str(tmp_path / "levelled.png")]) == 0
    tags = _read_tags(tmp_path / "posed.png")
    pitch, roll = tags["XMP-GPano:PosePitchDegrees"], tags["XMP-GPano:PoseRollDegrees"]
    assert (pitch, roll) == pytest.approx((4.0, -3.0), abs=0.3)
    assert (tags["XMP-GPano:FullPanoWidthPixels"], tags["XMP-GPano:CroppedAreaImageHeightPixels"]) == (1024, 512)
    assert np.array_equal(read_image(tmp_path / "posed.png"), image)
    # the bytes: the input's with only the XMP chunk changed
    before, after = source.read_bytes(), (tmp_path / "posed.png").read_bytes()
    strip = lambda data: metadata.with_xmp(data, b"")  # noqa: E731 - both without their XMP
    assert strip(before) == strip(after)
    assert _icc_of(tmp_path / "posed.png") == _icc_of(source)
    # a viewer (Pannellum: horizonPitch, horizonRoll) shows the level direction d where the pixels have T d, T = R_y(p) R_x(r):
    # it turns the panorama by T⁻¹. level turns it by the shortest turn taking the same up to the zenith: the two differ by a
    # turn Q about the vertical (about p r / 2 radians: 0.1° here), found from the pose alone
    levelled = read_image(tmp_path / "levelled.png")
    tilt = tilt_rotation(pitch, roll)
    shortest = Moebius.levelling(coords.xyz_to_lonlat(tilt @ [0.0, 0.0, 1.0])).apply_xyz(np.eye(3)).T
    q = shortest @ tilt
    assert abs(np.degrees(np.arctan2(q[1, 0], q[0, 0]))) < 0.2 and np.allclose(q[2], [0, 0, 1], atol=1e-12)
    shown = ow.warp_moebius(image, Moebius.from_rotation(q @ tilt.T)).image
    diff = np.abs(shown.astype(np.int64) - levelled)
    assert diff.max() <= 2, f"the viewer's turn and level's differ by up to {diff.max()} grey levels"
    as_viewers_show = ow.warp_moebius(image, Moebius.from_rotation(tilt.T)).image  # without Q: 0.1° round the vertical
    assert np.abs(as_viewers_show.astype(np.int64) - levelled)[64:448].mean() <= 2.0
    wrong = ow.warp_moebius(image, Moebius.from_rotation(tilt_rotation(-pitch, -roll).T)).image  # the opposite signs: far off
    assert np.abs(wrong.astype(np.int64) - levelled)[64:448].mean() > 10


def test_level_pose_is_the_gpano_pose():
    found = ow.level(synthetic_room(1024, pitch=-5.0, roll=2.0, seed=3).image)
    assert found.pose() == {"PosePitchDegrees": found.pitch, "PoseRollDegrees": found.roll}
    assert found.pose()["PosePitchDegrees"] == pytest.approx(-5.0, abs=0.3)


def test_pose_only_refuses_what_it_cannot_do(tmp_path, capsys):
    write_image(tmp_path / "a.png", synthetic_room(256, seed=3).image)
    assert main(["level", str(tmp_path / "a.png"), "-o", str(tmp_path / "b.jpg"), "--pose-only"]) == 2
    assert "name the output .png" in capsys.readouterr().err
    assert main(["level", str(tmp_path / "a.png"), "-o", str(tmp_path / "b.png"), "--pose-only", "--width", "128"]) == 2
    assert "--width" in capsys.readouterr().err
    assert not (tmp_path / "b.png").exists() and not (tmp_path / "b.jpg").exists()
