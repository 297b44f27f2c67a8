"""Never fold: the default mode never folds the sphere; the paper's mode stays as it is.

Every scene is warped by the default options and checked on the output grid: no pixel turned
over, on the map that placed the pixels and on the exact blend, and every marked line within
:data:`~omniwidget.evaluate.quality.RELAXED_PX` of straight along its whole arc unless a
warning says that it gave way where the blend folded on it. The generated families
are measured on the report half of the seeds (odd), never the half the untangling's
constants were chosen on (even seeds, ``bench/bench_default.py --half choose``); the real
panoramas of ``../shared/data`` with their suggested lines as ``omniwidget suggest`` writes them.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from omniwidget.document.handles import Handles, LineHandle, Options
from omniwidget.evaluate.quality import RELAXED_PX, chain_straightness
from omniwidget.evaluate.scenes import FAMILIES, family_scene
from omniwidget.raster.fold import fold_over
from omniwidget.raster.pipeline import warp
from omniwidget.sphere import coords
from omniwidget.sphere.arcs import crossing_pairs

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
PHOTOS = ("brooklyn_street_12k", "city_parking", "courtyard", "grabodrertorv", "hotel_room", "lamppost", "studio_office")
#: Seeds of the report half (odd; the constants were chosen on the even ones) that CI warps, at 2048 and at 1024;
#: the bench (``python bench/bench_default.py``) measures all twenty of the half at 1024.
REPORT = ((1, 2048), (3, 1024))


def _check_one_to_one(result, width: int, exact: bool = True) -> None:
    """No pixel turned over on the map that placed the pixels and, with ``exact``, on the blend evaluated exactly at
    every pixel (at 2048 with 40 suggested lines that evaluation costs as much as the warp: the 1024 scenes check it)."""
    assert result.folds.area == 0 and not result.folds.mask.any(), result.folds.area
    assert fold_over(result.placed_map()).area == 0
    if exact:
        assert fold_over(result.inverse_map(np.float64)).area == 0
    assert result.image.shape[1] == width


def _check_lines(result) -> None:
    """Every line within RELAXED_PX, or named by a warning: giving way where the blend folded on it (or beyond
    untangling), or crossing another line in the output."""
    figures = chain_straightness(result)
    gave_way = set(result.gave_way)  # maps relaxed where no window cleared the fold, or lines through an untangled window
    said = {int(m.group(1)) for w in result.warnings if (m := re.match(r"handles\[(\d+)\] \(line\) gives way where the blend folded", w))}
    for w in result.warnings:
        if " give way where their blend folded beyond untangling" in w:
            said |= {int(i) for i in re.findall(r"handles\[(\d+)\]", w.split(" give way ")[0])}
    assert said == gave_way, (said, result.gave_way)  # the warnings name the same handles
    for w in result.warnings:
        if w.endswith("cross each other in the output"):  # a conflict said: suggested room 3 at 1024, a line across
            gave_way |= {int(i) for i in re.findall(r"handles\[(\d+)\]", w)}  # one kept as it is by a pole (0.56 px)
    # a line that crosses one of those in the input meets it where it gave way (suggested room 3 at 1024: handles[19],
    # 0.585 px with the lines' ends held, crosses handles[12], kept by a pole and giving way where it folded)
    order = [i for i, h in enumerate(result.handles.handles) if isinstance(h, LineHandle)]
    arcs = [coords.geodesic(result.handles.handles[i].start, result.handles.handles[i].end, np.linspace(0.0, 1.0, 65)) for i in order]
    pairs = [(order[a], order[b]) for a, b in crossing_pairs(arcs)]
    gave_way |= {b for a, b in pairs if a in gave_way} | {a for a, b in pairs if b in gave_way}
    for chain, figure in zip(result.constraints.chains, figures, strict=True):
        handle = result.controls[result.constraints.lines[chain[0]][0]].handle
        assert figure <= RELAXED_PX or handle in gave_way, (handle, figure, result.warnings)


def _warp(image, doc):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return warp(image, doc)


@pytest.mark.slow  # two report seeds of every family, one at 2048 and one at 1024; the fast loop runs its twin below
@pytest.mark.parametrize("family", FAMILIES)
def test_the_default_mode_never_folds_on_the_report_half(family):
    for seed, width in REPORT:
        scene, doc, _ = family_scene(family, seed, width)
        result = _warp(scene.image, doc)
        _check_one_to_one(result, width, exact=width <= 1024)
        _check_lines(result)


@pytest.mark.parametrize(("family", "seed"), [("long", 7), ("room_edges", 1), ("mixed", 3)])
def test_the_default_mode_never_folds_at_1024(family, seed):
    """Scenes whose blend folds (long 7: 0.52% of the sphere at 1024 before untangling): none is left."""
    scene, doc, _ = family_scene(family, seed, 1024)
    result = _warp(scene.image, doc)
    _check_one_to_one(result, 1024)
    _check_lines(result)


def test_a_scene_that_folds_is_untangled_and_says_which_handles_gave_way():
    # the one odd seed of 1-19 whose default blend still folds with the harmonic fill (long 3, which folded 3.3% of the
    # sphere in the paper's mode, no longer does in the default's); the paper's mode folds 0.024% of the sphere here
    scene, doc, _ = family_scene("long", 5, 1024)
    paper = _warp(scene.image, Handles(doc.handles, Options(anchor=None)))
    default = _warp(scene.image, doc)
    assert paper.folds.area > 1e-4  # the paper's mode is as it was: it folds here, and says so
    assert any("folds over near" in w for w in paper.warnings) and not any("untangled" in w for w in paper.warnings)
    (given,) = [w for w in default.warnings if w.startswith("the blend folded over near")]
    assert re.search(r"handles\[\d+\] \(line\)", given) and "the warp is one-to-one" in given
    moved = float(re.search(r"give way by up to ([\d.]+) px", given).group(1))
    assert 0 < moved < 1024 / 8, given
    # the map differs from the blend only in the untangled windows: a few, not the sphere
    from omniwidget.raster.pipeline import blend_coordinates
    from omniwidget.raster.warping import coordinates_lonlat

    blended, _, _ = blend_coordinates(default, 1024, scene.image.shape[1])
    difference = np.abs(((coordinates_lonlat(blended, scene.image.shape[1]) - default.placed_map() + 180) % 360) - 180)
    changed = np.any(difference > 1e-6, axis=-1)
    assert 0 < changed.mean() < 0.05, changed.mean()


@pytest.mark.slow  # seven panoramas at 2048 with their suggestions (about 3 min)
@pytest.mark.parametrize("name", PHOTOS)
def test_real_panoramas_with_their_suggested_lines_never_fold(name):
    import cv2

    import omniwidget as ow
    from omniwidget.io.images import read_image

    path = DATA / f"{name}.jpg"
    if not path.exists():  # CI lays ../shared beside the checkout: there a missing photo is a failure
        message = f"{path} is a test input beside the checkout (../shared/data)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    image = cv2.resize(read_image(path), (2048, 1024), interpolation=cv2.INTER_AREA)
    doc = ow.suggestions_to_handles(ow.suggest_lines(image))  # what `omniwidget suggest` writes
    result = _warp(image, doc)
    _check_one_to_one(result, 2048, exact=False)  # the placed map: what the pixels show
