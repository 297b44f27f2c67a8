"""The README and DEVELOP.md as they are read on the repository's page: every link and picture is there, every
headline figure links to a section of bench/RESULTS.md that exists, and the set-up commands are the ones CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
DEVELOP = (ROOT / "DEVELOP.md").read_text(encoding="utf-8")
CI = (ROOT / ".ci" / "run").read_text(encoding="utf-8")

#: ``[text](target)`` and ``![alt](target)``, the target without a title.
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(markdown: str) -> set[str]:
    """The anchors of every heading, a repeated one numbered as GitHub numbers it (``-1``, ``-2``, ...)."""
    seen: dict[str, int] = {}
    for line in markdown.splitlines():
        if match := re.match(r"#{1,6} (.+)", line):
            slug = _slug(match.group(1))
            seen[slug] = seen.get(slug, -1) + 1
            if seen[slug]:
                seen[f"{slug}-{seen[slug]}"] = 0
    return set(seen)


def _local_links(markdown: str) -> list[str]:
    return [t for t in LINK.findall(markdown) if not re.match(r"[a-z]+:", t)]


def test_the_slug_is_githubs():
    assert _slug("360° videos") == "360-videos"
    assert _slug("Notebook 04's comparison and the rival") == "notebook-04s-comparison-and-the-rival"
    assert _anchors("## A\n## A\n") == {"a", "a-1"}


def test_every_local_link_and_picture_of_the_readme_and_develop_is_there():
    for name, text in (("README.md", README), ("DEVELOP.md", DEVELOP)):
        links = _local_links(text)
        assert links or name == "DEVELOP.md"
        missing = [t for t in links if not (ROOT / t.partition("#")[0]).exists()]
        assert missing == [], (name, missing)


def test_the_readme_shows_the_pictures():
    for picture in ("editor.png", "demo_before_after.jpg", "suggest_level.jpg", "straighten.jpg", "weights.png"):
        assert f"](docs/images/{picture})" in README, picture


def test_each_headline_figure_links_to_a_section_of_results_that_exists():
    results = (ROOT / "bench" / "RESULTS.md").read_text(encoding="utf-8")
    anchors = _anchors(results)
    linked = [t.partition("#")[2] for t in _local_links(README) if t.startswith("bench/RESULTS.md#")]
    assert len(linked) >= 5
    assert [a for a in linked if a not in anchors] == []


def test_the_readmes_test_commands_are_the_ones_ci_runs():
    block = README.split("## Set up", 1)[1].split("```", 2)[1]
    lines = [line.partition("#")[0] for line in block.splitlines() if not line.startswith("#")]
    commands = [c.strip() for line in lines for c in line.split("&&")]
    checks = [c for c in commands if c.startswith(("python -m ", "npm "))]
    assert {c.split()[2] for c in checks if c.startswith("python")} == {"ruff", "mypy", "pytest"}
    assert all(c in CI for c in checks), [c for c in checks if c not in CI]


def test_the_readme_is_a_readme():
    lines = README.count("\n")
    assert 150 <= lines <= 250, lines
    assert re.search(r"issue[ -]?#?\d+", README, flags=re.IGNORECASE) is None
