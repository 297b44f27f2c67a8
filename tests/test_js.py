"""The editor's JavaScript (omniwidget/widget/static/*.js): ``node --test tests/js/`` and the bundle anywidget loads.

The pure modules of the front end (the sphere, the handles' shapes, the view, hit testing,
the edits of the handles document, the handles' Möbius maps) each have a file of Node tests
in ``tests/js``, run here by Node's own test runner (Node from Debian, no package). The live
drag rebuilds the dragged handle's maps in the browser every frame; they must be the maps
the kernel builds on release, so Python writes its own results for random handles to a JSON
file that ``tests/js/moebius.test.mjs`` compares with (without it those tests are skipped).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from omniwidget.method.deformation import deform
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius
from tests.conftest import offset, random_lonlat

REPO = Path(__file__).resolve().parents[1]
JS_TESTS = REPO / "tests" / "js"


def node_command() -> str:
    """The node executable; skipped without it, failed when the real-browser tests must run (CI)."""
    node = shutil.which("node")
    if node is None:
        if os.environ.get("OMNIWIDGET_BROWSER_TESTS") == "1":
            pytest.fail("node is needed for the JavaScript tests (apt-get install nodejs)")
        pytest.skip("node is not installed")
    return node


def _images(m: Moebius, probes: np.ndarray) -> list:
    return m.apply_xyz(coords.lonlat_to_xyz(probes)).tolist()


def _cases(rng: np.random.Generator) -> dict:
    probes = np.vstack([random_lonlat(rng, 12), [[0, 90], [0, -90], [-180, 0]]])
    out: dict = {"probes": probes.tolist(), "point_map": [], "from_points": [], "arrow_tip": [], "best_rotation": [], "drag_maps": []}
    for _ in range(20):
        p, t = random_lonlat(rng, 2)
        args = [p.tolist(), t.tolist(), float(rng.uniform(0.2, 4)), float(rng.uniform(-180, 180))]
        out["point_map"].append({"args": args, "images": _images(Moebius.point_map(*args), probes)})
        src, dst = random_lonlat(rng, 3), random_lonlat(rng, 3)
        out["from_points"].append({"src": src.tolist(), "dst": dst.tolist(), "images": _images(Moebius.from_points(src, dst), probes)})
        h = PointHandle(tuple(p), tuple(t), rotation=float(rng.uniform(-90, 90)), scale=float(rng.uniform(0.5, 2)))
        which = "east" if rng.random() < 0.5 else "west"
        tip = offset(h.final, rng.uniform(0, 360), rng.uniform(5, 40))
        turned = h.with_arrow_tip(tip, which)
        out["arrow_tip"].append({"final": list(h.final), "tip": tip.tolist(), "which": which, "scale": turned.scale, "rotation": turned.rotation})
        n = int(rng.integers(3, 8))
        source, target = random_lonlat(rng, n), random_lonlat(rng, n)
        out["best_rotation"].append({"source": source.tolist(), "target": target.tolist(), "rotation": coords.best_rotation(source, target).tolist()})

        # the maps of a drag on the result, as the kernel builds them on release
        doc = {"kind": "point", "position": list(h.position), "target": list(h.final), "scale": h.scale, "rotation": h.rotation}
        moved = h.target_points()
        moved[0] = offset(h.final, rng.uniform(0, 360), rng.uniform(1, 30))
        out["drag_maps"].append(
            {"what": "point centre", "handle": doc, "points": moved.tolist(), "part": 0, "carry": True,
             "images": [_images(PointHandle(h.position, tuple(moved[0]), h.rotation, h.scale).moebius(), probes)]}
        )
        part = 1 if which == "east" else 2
        tips = h.target_points()
        tips[part] = tip
        out["drag_maps"].append(
            {"what": f"point {which} arrow", "handle": doc, "points": tips.tolist(), "part": part, "carry": True,
             "images": [_images(turned.moebius(), probes)]}
        )
        start, end = random_lonlat(rng, 2)
        line = LineHandle(tuple(start), tuple(end), rectify=False)
        targets = np.array([offset(q, rng.uniform(0, 360), rng.uniform(0, 10)) for q in line.control_points()])
        out["drag_maps"].append(
            {"what": "line", "handle": {"kind": "line", "start": start.tolist(), "end": end.tolist(), "rectify": True},
             "points": targets.tolist(), "part": 2, "carry": True,
             "images": [_images(LineHandle(tuple(start), tuple(end), rectify=False, targets=tuple(map(tuple, targets))).moebius(), probes)]}
        )
        centre = random_lonlat(rng, 1)[0]
        vertices = np.array([offset(centre, a, rng.uniform(5, 30)) for a in np.sort(rng.uniform(0, 360, n))])
        shift = Moebius.point_map(centre, offset(centre, rng.uniform(0, 360), rng.uniform(1, 40)), 1.0, float(rng.uniform(-30, 30)))
        finals = shift(vertices)
        finals[0] = offset(finals[0], rng.uniform(0, 360), rng.uniform(0, 5))  # bent a little
        cage = CageHandle(tuple(map(tuple, vertices)), tuple(map(tuple, finals)))
        for carry in (True, False):
            out["drag_maps"].append(
                {"what": f"cage, carry={carry}", "handle": {"kind": "cage", "vertices": vertices.tolist()}, "points": finals.tolist(),
                 "part": 0, "carry": carry, "images": [_images(mv, probes) for mv in cage.vertex_maps(carry=carry)]}
            )
        # the same with the document levelled (options.up): the kernel's own control maps
        up = (float(rng.uniform(-180, 180)), float(rng.uniform(60, 89)))
        turn = Moebius.levelling(up)
        for what, handle, points, part in (
            ("levelled point centre", PointHandle(h.position, tuple(moved[0]), h.rotation, h.scale), moved, 0),
            ("levelled line", LineHandle(tuple(start), tuple(end), rectify=False, targets=tuple(map(tuple, targets))), targets, 2),
            ("levelled cage", cage, finals, 0),
        ):
            controls = [c for c in deform(Handles((handle,), Options(up=up))).controls if c.handle == 0]
            controls = controls[:1] if isinstance(handle, PointHandle) else controls  # a point's own map (then the rungs of its reach)
            out["drag_maps"].append(
                {"what": what, "handle": Handles((handle,)).to_dict()["handles"][0], "points": np.asarray(points).tolist(), "part": part, "carry": True,
                 "turn": turn.as_dict(), "images": [_images(c.moebius, probes) for c in controls]}
            )
    return out


def test_the_javascript_tests_pass(tmp_path, rng):
    """Every test of every file in tests/js runs (none skipped: the Python cases are there) and passes."""
    node = node_command()
    cases = tmp_path / "cases.json"
    cases.write_text(json.dumps(_cases(rng)))
    files = sorted(JS_TESTS.glob("*.test.mjs"))  # node --test tests/js/, the files named: Node 22 reads arguments as globs, not folders
    run = subprocess.run(
        [node, "--test", *map(str, files)],
        env={**os.environ, "OMNIWIDGET_JS_CASES": str(cases)},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    written = sum(len(re.findall(r"^test\(", f.read_text(encoding="utf-8"), re.M)) for f in files)
    summary = dict(re.findall(r"^# (tests|pass|fail|cancelled|skipped|todo) (\d+)$", run.stdout, re.M))
    assert summary == {"tests": str(written), "pass": str(written), "fail": "0", "cancelled": "0", "skipped": "0", "todo": "0"}, run.stdout


def test_the_bundle_is_one_module_node_can_load(tmp_path):
    """editor.py's bundle (editor.js with the modules it imports, and theirs, inlined) is one ES module with ``render``."""
    from omniwidget.widget.editor import _bundle

    node = node_command()
    bundle = _bundle()
    assert not re.search(r"^\s*import\s", bundle, re.M), "an import left in the bundle"
    path = tmp_path / "editor.bundle.mjs"
    path.write_text(bundle, encoding="utf-8")
    script = f"import({json.dumps(path.as_uri())}).then((m) => console.log(typeof m.default.render))"
    run = subprocess.run([node, "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and run.stdout.strip() == "function", run.stdout + run.stderr
