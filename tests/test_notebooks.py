"""The teaching notebooks run top to bottom, headless, without error (nbclient, a real kernel).

Each numbered notebook is executed once per session; the tests then read what it printed:
notebook 04's comparison tables are checked here as numbers (their ``application/json``
output), so what a lecturer shows is what was measured.
"""

import time
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("[0-9][0-9]_*.ipynb"))
#: All of them together must run in under 5 minutes (issue 6); each gets this much.
TIMEOUT = 240
#: Seconds each notebook took, for the total below.
SECONDS: dict[str, float] = {}


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    """``executed(path)``: the notebook run top to bottom (once per session), with its outputs."""
    cache = {}

    def run(path: Path):
        if path not in cache:
            nb = nbformat.read(path, as_version=4)
            assert all(not cell.get("outputs") for cell in nb.cells if cell.cell_type == "code"), f"{path.name} is committed with outputs"
            folder = tmp_path_factory.mktemp(path.stem)
            start = time.perf_counter()
            nbclient.NotebookClient(nb, timeout=TIMEOUT, kernel_name="python3", resources={"metadata": {"path": str(folder)}}).execute()
            SECONDS[path.name] = time.perf_counter() - start
            print(f"{path.name}: {SECONDS[path.name]:.1f} s")
            cache[path] = nb
        return cache[path]

    return run


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, executed):
    nb = executed(path)
    errors = [f"{o.ename}: {o.evalue}" for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors


def test_there_are_notebooks():
    assert [p.name[:2] for p in NOTEBOOKS] == [f"{i:02d}" for i in range(7)]


def test_all_notebooks_together_take_under_five_minutes(executed):
    for path in NOTEBOOKS:
        executed(path)
    assert sum(SECONDS.values()) < 300, SECONDS


def _table(nb, tag: str) -> dict:
    """The ``application/json`` output of the cell tagged ``tag``: a Comparison's figures by method."""
    cells = [c for c in nb.cells if tag in c.get("metadata", {}).get("tags", [])]
    assert len(cells) == 1, f"one cell tagged {tag!r} expected"
    tables = [o.data["application/json"] for o in cells[0].outputs if o.output_type == "execute_result" and "application/json" in o.data]
    assert len(tables) == 1, f"the cell tagged {tag!r} shows no comparison table"
    return tables[0]


def test_notebook_04_table_bbw_is_smooth_piecewise_tears_gaussian_bends(executed):
    """Issue 6: on the notebook's own room, BBW neither folds nor tears; piecewise tears; the Gaussian bends close lines."""
    nb = executed(next(p for p in NOTEBOOKS if p.name.startswith("04_")))
    room = _table(nb, "comparison-room")
    bbw, piecewise, gaussian = room["bbw"], room["piecewise_constant"], room["gaussian_2017"]
    assert bbw["fold_over"] == 0 and bbw["tear"] < 1.0, bbw
    assert bbw["coverage"] > 0.99 and bbw["cage_motion"] < 0.01, bbw
    assert piecewise["tear"] > 20 * max(bbw["tear"], 1.0), (piecewise["tear"], bbw["tear"])
    assert gaussian["straightness"] > bbw["straightness"] + 0.3, (gaussian["straightness"], bbw["straightness"])
    close = _table(nb, "comparison-close")
    assert close["bbw"]["fold_over"] == 0 and close["bbw"]["tear"] < 1.0, close["bbw"]
    assert close["gaussian_2017"]["straightness"] > 4 * close["bbw"]["straightness"] + 0.1, close
    assert close["piecewise_constant"]["tear"] > 10, close["piecewise_constant"]


def test_notebook_04_still_background_figures_are_the_ones_its_text_gives(executed):
    """Issue 9: the section compares the paper (anchor: null) with the still background; its prose quotes the printed figures."""
    nb = executed(next(p for p in NOTEBOOKS if p.name.startswith("04_")))
    cell = next(c for c in nb.cells if "still-background" in c.get("metadata", {}).get("tags", []))
    text = "".join(o.get("text", "") for o in cell.outputs if o.output_type == "stream")
    paper, still = (line.strip() for line in text.splitlines()[1::2])
    for quoted in ("folds 2.5%", "moved 14° on average", "distortion 8.4", "far from the handles moved 25°"):
        assert quoted in paper, paper
    for quoted in ("folds 0%", "moved 0.066° on average", "distortion 0.025", "far from the handles still"):
        assert quoted in still, still
    prose = next(c.source for c in nb.cells if c.cell_type == "markdown" and c.source.startswith("## Beyond the paper"))
    assert all(figure in prose for figure in ("2.5%", "14°", "25°", "0.066°", "0.025"))
