#!/usr/bin/env python
"""Structure first: the suggested lines against the box's own edges, raw and chosen, run on demand (not a test).

Usage::

    python bench/bench_structure.py                      # the choosing table (even seeds), the report (odd seeds), the photos
    python bench/bench_structure.py --rooms 20 --photos ../shared/data --repeat 5
    python bench/bench_structure.py --no-choose           # the report and the photos only

Generated box rooms (:func:`omniwidget.evaluate.scenes.box_room`, grid paint, noise, tilts
up to 20°) at 2048 x 1024, the width the detector works at. Each room's lines are found
once (``suggest_lines(structure=False)``, every line, ranked by confidence) and the choice
(:func:`omniwidget.detect.structure.choose_structure`, what ``suggest_lines`` does by
default) is made on them with the constants tried, exactly as ``suggest_lines`` makes it:
the vertical found from the lines, the image's sides looked at, at most 40 kept.

Printed, as markdown tables for bench/RESULTS.md:

- the choosing table: each constant tried on the even seeds, the worst and median coverage
  (share of the box's 12 edges, by arc length, within 0.5° of a kept line) and precision
  (share of the kept lines' length within 0.5° of an edge);
- the report half (odd seeds): per room, the raw list's figures (every line; its first 40)
  against the chosen set's, and the worst and median;
- with ``--photos``: each panorama's lines found, kept and dropped (and why, by reason),
  and the time of ``suggest_lines`` against ``suggest_lines(structure=False)``, medians of
  ``--repeat`` runs in turns in this process.
"""

from __future__ import annotations

import argparse
import collections
import statistics
import sys
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from omniwidget.detect import structure, suggest_lines
from omniwidget.detect.lines import DETECT_WIDTH, Suggestion
from omniwidget.evaluate.scenes import Scene, box_room, edge_coverage, edge_precision
from omniwidget.sphere import coords

WIDTH = 2048
MAX_LINES = 40
SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp")

#: The constants tried on the even seeds, each alone, the others at their chosen values.
TRIED: dict[str, tuple[float, ...]] = {
    "FAMILY_SIZE": (2, 3, 4, 6),
    "MARK_BOUNDS": (1, 3, 99),
    "TEXTURE_CROSSINGS": (1, 2, 3),
    "BOUND_WEIGHT": (0.5, 1.0, 1.5),
    "ALIKE": (4.0, 8.0, 16.0, 24.0),
    "CLOSE_DISTANCE": (1.5, 2.5, 3.5),
    "SIDE_WEIGHT": (0.0, 0.5),
}


@dataclass
class Room:
    seed: int
    scene: Scene
    raw: list[Suggestion]
    up: tuple[float, float]


def rooms(seeds: range) -> list[Room]:
    out = []
    for seed in seeds:
        scene = box_room(seed, WIDTH)
        raw = suggest_lines(scene.image, max_lines=None, structure=False)
        v, _ = structure.structure_up(raw, WIDTH)
        lon, lat = coords.xyz_to_lonlat(v).tolist()
        out.append(Room(seed, scene, raw, (float(lon), float(lat))))
        print(f"  room {seed}: {len(raw)} lines found", file=sys.stderr, flush=True)
    return out


def chosen(room: Room) -> tuple[Suggestion, ...]:
    """What ``suggest_lines`` keeps on the room (its up found again from the lines, as it does)."""
    return structure.choose_structure(room.raw, None, width=WIDTH, max_lines=MAX_LINES, image=room.scene.image).kept


def figures(room: Room, lines: tuple[Suggestion, ...] | list[Suggestion]) -> tuple[float, float]:
    return edge_coverage(room.scene, lines), edge_precision(room.scene, lines)


def choosing_table(even: list[Room]) -> None:
    print("\n### The choosing table (even seeds)\n")
    print("| constant | value | coverage worst | coverage median | precision worst | precision median |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, values in TRIED.items():
        chosen_value = getattr(structure, name)
        for value in values:
            setattr(structure, name, type(chosen_value)(value))
            c, p = np.array([figures(room, chosen(room)) for room in even]).T
            mark = " (chosen)" if value == chosen_value else ""
            print(f"| `{name}` | {value:g}{mark} | {c.min():.3f} | {np.median(c):.3f} | {p.min():.3f} | {np.median(p):.3f} |")
        setattr(structure, name, chosen_value)


def report(odd: list[Room]) -> None:
    print("\n### The report half (odd seeds)\n")
    print("| seed | lines found | coverage, raw (all / first 40) | precision, raw (all / first 40) | kept | coverage, chosen | precision, chosen |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    rows = []
    for room in odd:
        kept = chosen(room)
        all_c, all_p = figures(room, room.raw)
        top_c, top_p = figures(room, room.raw[:MAX_LINES])
        c, p = figures(room, kept)
        rows.append((all_c, all_p, top_c, top_p, c, p, len(kept)))
        print(f"| {room.seed} | {len(room.raw)} | {all_c:.3f} / {top_c:.3f} | {all_p:.3f} / {top_p:.3f} | {len(kept)} | {c:.3f} | {p:.3f} |")
    a = np.array(rows)
    for what, f in (("worst", np.min), ("median", np.median)):
        print(f"| {what} | | {f(a[:, 0]):.3f} / {f(a[:, 2]):.3f} | {f(a[:, 1]):.3f} / {f(a[:, 3]):.3f} | | {f(a[:, 4]):.3f} | {f(a[:, 5]):.3f} |")
    met = int(np.sum((a[:, 4] >= 0.8) & (a[:, 5] >= 0.9)))
    print(f"\nBoth targets (coverage >= 0.8, precision >= 0.9) met on {met} of {len(rows)} rooms; the raw list's coverage (all lines) is the most the choice can keep.")


def photos(folder: Path, repeat: int) -> None:
    from omniwidget.io.images import read_panorama

    print("\n### The photographs\n")
    print("| panorama | lines found | kept (vertical / horizontal / other) | dropped: texture / crossing / beside a kept line / short 'other' / beyond 40 | `suggest_lines` | `structure=False` | ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for path in sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES):
        image = read_panorama(path)
        raw = suggest_lines(image, max_lines=None, structure=False)
        choice = structure.choose_structure(raw, None, width=min(image.shape[1], DETECT_WIDTH), max_lines=MAX_LINES, image=image)
        kinds = collections.Counter(s.kind for s in choice.kept)
        reasons = collections.Counter(_reason(why) for _, why in choice.dropped)
        times: dict[str, list[float]] = {"chosen": [], "raw": []}
        runs = {"chosen": partial(suggest_lines, image), "raw": partial(suggest_lines, image, structure=False)}
        for run in runs.values():
            run()  # warm up
        for _ in range(repeat):
            for name, run in runs.items():
                start = time.perf_counter()
                run()
                times[name].append(time.perf_counter() - start)
        t_chosen, t_raw = statistics.median(times["chosen"]), statistics.median(times["raw"])
        dropped = " / ".join(str(reasons[k]) for k in ("texture", "crossing", "beside", "short", "beyond"))
        print(
            f"| {path.name} | {len(raw)} | {len(choice.kept)} ({kinds['vertical']} / {kinds['horizontal']} / {kinds['other']}) | {dropped} "
            f"| {t_chosen:.3f} s | {t_raw:.3f} s | {t_chosen / t_raw:.2f}x |"
        )


def _reason(why: str) -> str:
    if "texture" in why or "mark on a surface" in why:
        return "texture"
    if why.startswith("crosses"):
        return "crossing"
    if why.startswith("within"):
        return "beside"
    if why.startswith("kind 'other'"):
        return "short"
    return "beyond"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rooms", type=int, default=20, help="rooms in each half (even seeds to choose, odd to report)")
    parser.add_argument("--photos", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of each, in turns, per panorama")
    parser.add_argument("--no-choose", action="store_true", help="skip the choosing table")
    args = parser.parse_args()
    if not args.no_choose:
        choosing_table(rooms(range(0, 2 * args.rooms, 2)))
    report(rooms(range(1, 2 * args.rooms, 2)))
    if args.photos is not None and args.photos.is_dir():
        photos(args.photos, args.repeat)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
