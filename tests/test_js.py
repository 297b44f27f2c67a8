"""The editor's JavaScript (omniwidget/widget/static/*.js): ``node --test tests/js/`` and the bundle anywidget loads.

The pure modules of the front end (the sphere, the handles' shapes, the view, hit testing,
the edits of the handles document, the handles' Möbius maps) each have a file of Node tests
in ``tests/js``, run here by Node's own test runner (Node from Debian, no package). The live
drag rebuilds the dragged handle's maps in the browser every frame; they must be the maps
the kernel builds on release, so Python writes its own results for random handles to a JSON
file that ``tests/js/moebius.test.mjs`` compares with (without it those tests are skipped).

anywidget loads one module, ``static/editor.bundle.js``, built from the sources by esbuild
(``build.mjs``, ``npm run build``) and committed. Its first lines name its sources and their
SHA-256, which is checked here without Node; ``npm run check`` (``node build.mjs --check``,
esbuild from ``npm ci``) rebuilds it in memory and fails when the committed bundle differs
or a module uses what the bundle cannot take, which the deliberately bad modules below show.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import time
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
STATIC = REPO / "omniwidget" / "widget" / "static"
BUNDLE = STATIC / "editor.bundle.js"
BUILD = REPO / "build.mjs"


def node_command() -> str:
    """The node executable; skipped without it, failed when the real-browser tests must run (CI)."""
    node = shutil.which("node")
    if node is None:
        if os.environ.get("OMNIWIDGET_BROWSER_TESTS") == "1":
            pytest.fail("node is needed for the JavaScript tests (apt-get install nodejs)")
        pytest.skip("node is not installed")
    return node


def esbuild_installed() -> None:
    """Skipped without esbuild (``npm ci``), failed when the real-browser tests must run (CI)."""
    if not (REPO / "node_modules" / "esbuild" / "package.json").is_file():
        if os.environ.get("OMNIWIDGET_BROWSER_TESTS") == "1":
            pytest.fail("esbuild is needed to check the editor's bundle (npm ci at the repository's root)")
        pytest.skip("esbuild is not installed (npm ci)")


def build_check(static: Path = STATIC) -> subprocess.CompletedProcess:
    """``node build.mjs --check`` over the sources and bundle in ``static``."""
    node = node_command()
    esbuild_installed()
    return subprocess.run([node, str(BUILD), "--check", "--static", str(static)], capture_output=True, text=True, timeout=60, cwd=REPO)


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
    """The bundle anywidget loads (editor.js with the modules it imports, and theirs, inlined) is one ES module with ``render``."""
    node = node_command()
    bundle = BUNDLE.read_text(encoding="utf-8")
    assert not re.search(r"^\s*import\s", bundle, re.M), "an import left in the bundle"
    path = tmp_path / "editor.bundle.mjs"
    path.write_text(bundle, encoding="utf-8")
    script = f"import({json.dumps(path.as_uri())}).then((m) => console.log(typeof m.default.render))"
    run = subprocess.run([node, "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and run.stdout.strip() == "function", run.stdout + run.stderr


def test_the_editor_gives_anywidget_the_bundle_as_a_file_it_can_watch():
    """``Editor._esm`` is the bundle's file (anywidget's hot reload watches a path, never a string), its text the bundle's."""
    from anywidget._file_contents import FileContents

    from omniwidget.widget.editor import Editor

    assert isinstance(Editor._esm, FileContents)
    assert Editor._esm._path == BUNDLE
    assert str(Editor._esm) == BUNDLE.read_text(encoding="utf-8")


def _sources_digest(static: Path, sources: list[str]) -> str:
    """build.mjs's digest: each source's name, a NUL, its bytes and a NUL, in name order."""
    digest = hashlib.sha256()
    for name in sorted(sources):
        digest.update(name.encode() + b"\0" + (static / name).read_bytes() + b"\0")
    return digest.hexdigest()


def test_the_bundle_is_built_from_the_sources_as_they_are():
    """The bundle's sources are every module of static/ (none left out), and their digest the one it was built from.

    This needs no Node: a source edited without ``npm run build`` fails here everywhere.
    """
    head = BUNDLE.read_text(encoding="utf-8")[:2000]
    sources = re.search(r"^// sources: (.+)$", head, re.M)
    digest = re.search(r"^// sources sha256: ([0-9a-f]{64})$", head, re.M)
    assert sources and digest, "the bundle does not name its sources: rebuild it with npm run build"
    names = sources[1].split()
    assert sorted(names) == sorted(p.name for p in STATIC.glob("*.js") if p != BUNDLE), "a module of static/ not in the bundle"
    assert _sources_digest(STATIC, names) == digest[1], "editor.bundle.js is out of date with its sources: run npm run build"


def test_the_committed_bundle_is_what_the_sources_build_to():
    """``npm run check``: esbuild rebuilds the bundle in memory, byte for byte the committed one."""
    started = time.perf_counter()
    run = build_check()
    assert run.returncode == 0, run.stdout + run.stderr
    assert "is up to date" in run.stdout
    assert time.perf_counter() - started < 30


def _sources_with(tmp_path: Path, module: str, files: dict[str, str] | None = None) -> Path:
    """A copy of static/ whose editor.js imports ``bad.js`` holding ``module`` (and more ``files`` beside it)."""
    static = tmp_path / "static"
    shutil.copytree(STATIC, static)
    (static / "bad.js").write_text(module, encoding="utf-8")
    for name, text in (files or {}).items():
        (static / name).parent.mkdir(exist_ok=True)
        (static / name).write_text(text, encoding="utf-8")
    editor = (static / "editor.js").read_text(encoding="utf-8")
    first = editor.index("\nimport ") + 1
    (static / "editor.js").write_text(editor[:first] + 'import { bad } from "./bad.js";\nconsole.log(bad);\n' + editor[first:], encoding="utf-8")
    return static


def test_the_check_fails_on_a_source_changed_without_a_rebuild(tmp_path):
    static = tmp_path / "static"
    shutil.copytree(STATIC, static)
    assert build_check(static).returncode == 0  # the copy as it is passes
    sphere = static / "sphere.js"
    sphere.write_text(sphere.read_text(encoding="utf-8").replace("export const DEG = Math.PI / 180;", "export const DEG = Math.PI / 180.0 + 0;"), encoding="utf-8")
    run = build_check(static)
    assert run.returncode == 1 and "editor.bundle.js is out of date with its sources: run npm run build" in run.stderr, run.stdout + run.stderr


BAD_MODULES = {
    "a file that is not there": ('import { x } from "./absent.js";\nexport const bad = x;\n', {}, 'bad.js:1:18: Could not resolve "./absent.js"'),
    "a package": ('import * as THREE from "three";\nexport const bad = THREE;\n', {}, 'bad.js:1:23: "three" is not a .js module of'),
    "a URL": ('import { x } from "https://esm.sh/x";\nexport const bad = x;\n', {}, '"https://esm.sh/x" is not a .js module of'),
    "a file of another folder": ('import { x } from "./more/x.js";\nexport const bad = x;\n', {"more/x.js": "export const x = 1;\n"}, '"./more/x.js" is not a .js module of'),
    "a stylesheet": ('import "./editor.css";\nexport const bad = 1;\n', {}, 'bad.js:1:7: "./editor.css" is not a .js module of'),
    "a name not exported": ('import { nothing } from "./sphere.js";\nexport const bad = nothing;\n', {}, 'bad.js:1:9: No matching export in "sphere.js" for import "nothing"'),
    "a computed import()": ('const name = "./sphere.js";\nexport const bad = () => import(name);\n', {}, "bad.js: a computed import() the bundle cannot resolve"),
    "require()": ('export const bad = require("./sphere.js");\n', {}, 'bad.js:1:27: "./sphere.js" is loaded by require-call'),
    "a syntax error": ("export const bad = ;\n", {}, 'bad.js:1:19: Unexpected ";"'),
    "what esbuild warns of": ("export const bad = { a: 1, a: 2 };\n", {}, 'bad.js:1:27: Duplicate key "a" in object literal'),
}


@pytest.mark.parametrize("what", BAD_MODULES)
def test_the_check_fails_on_a_module_the_bundle_cannot_take(tmp_path, what):
    """Each construct named in build.mjs, in a module editor.js imports: the check fails and names the module and why."""
    module, files, message = BAD_MODULES[what]
    run = build_check(_sources_with(tmp_path, module, files))
    assert run.returncode == 1, run.stdout + run.stderr
    assert "The editor's front end does not bundle:" in run.stderr and message in run.stderr, run.stderr
