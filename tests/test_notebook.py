"""The tutorial notebook examples/notebooks/first_rod.ipynb runs (issue 29 item 4): its
code cells are executed in order in one namespace, as a kernel would (nbclient and
jupytext are not in the environment), and its script twin first_rod.py holds the same
cells."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from PIL import Image

from quick_scenes import ROOT

NOTEBOOK = ROOT / "examples" / "notebooks" / "first_rod.ipynb"
TWIN = NOTEBOOK.with_suffix(".py")


def _cells(notebook) -> list[tuple[str, str]]:
    return [(c["cell_type"], "".join(c["source"]).strip("\n"))
            for c in json.loads(notebook.read_text())["cells"]]


def _twin_cells(script) -> list[tuple[str, str]]:
    """The '# %%' cells of a percent-format script (markdown lines without '# ')."""
    parts = re.split(r"^# %%(.*)$", script.read_text(), flags=re.M)
    cells = []
    for marker, body in zip(parts[1::2], parts[2::2]):
        body = body.strip("\n")
        if "[markdown]" in marker:
            body = "\n".join(line[2:] if line.startswith("# ") else line.lstrip("#")
                             for line in body.splitlines())
            cells.append(("markdown", body))
        else:
            cells.append(("code", body))
    return cells


def test_the_script_twin_holds_the_notebooks_cells():
    assert _cells(NOTEBOOK) == _twin_cells(TWIN)
    assert sum(kind == "code" for kind, _ in _cells(NOTEBOOK)) >= 5


@pytest.fixture
def executed(tmp_path, monkeypatch):
    """The notebook's namespace after running its code cells in a fresh folder that
    links the repository's scenes/ (the notebook writes its run folders there)."""
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for kind, source in _cells(NOTEBOOK):
        if kind == "code":
            exec(compile(source, str(NOTEBOOK), "exec"), namespace)    # noqa: S102
    return namespace


def test_the_notebook_runs_and_its_numbers_agree(executed):
    """Its runs completed; the fields it reads from rod.pvd end where the time series'
    tip is (the same state: 1e-12); the figure it draws has its two panels in one row
    (340 px, plots.py); the sprung cantilever's tip deflection is the hand formula to
    1e-2 (the formula is the small-deflection limit: at a deflection of 3 % of L the
    geometric and shear corrections are below 0.5 %)."""
    result, last = executed["result"], executed["last"]
    assert result.status == "completed" and executed["sprung"].status == "completed"
    end = last["points"][np.argmax(last["point"]["s"])]
    np.testing.assert_allclose(end, executed["tip"][-1], atol=1e-12)
    assert Image.open(executed["files"][0]).size == (1100, 340)
    assert executed["hand"] == pytest.approx(0.5 / 26.25 + 5.0 / 400.0, rel=1e-12)
    assert executed["computed"] == pytest.approx(executed["hand"], rel=1e-2)
