"""The picture of the modes (output/mode_picture.py, issue 27): ``dolfin-rod buckle``
writes buckle.png beside buckle.bp, and its drawn lines are the .bp file's mode shapes:
the clamped-free column's (8 cells) first two modes bend it in two perpendicular planes,
each drawn in its own plane, so the drawn polyline is the 3-D displaced centre line
seen without foreshortening (to round-off: the mode is exactly planar)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dolfin_rod import analyse, read_vtx
from dolfin_rod.output.mode_picture import mode_figure, view_plane


def test_buckle_writes_a_picture_of_its_modes(tmp_path):
    import matplotlib.image
    text = (Path(__file__).parents[1] / "scenes" / "column_buckling_modes.toml").read_text()
    scene = tmp_path / "column.toml"
    scene.write_text(text.replace("n_cells = 16", "n_cells = 8"))
    analyse(scene, "buckle", count=2, out=tmp_path / "out", quiet=True)
    out = tmp_path / "out"
    picture = matplotlib.image.imread(out / "buckle.png")
    assert picture.shape[0] > 200 and picture.shape[1] > 400          # two panels drawn
    steps = read_vtx(out / "buckle.bp")
    rows = json.loads((out / "buckle.json").read_text())["modes"]
    centre = np.zeros_like(steps[0]["points"])
    # the straight column (h = 1/8) shortened by the pre-load P / EA = (pi^2 / 8) / 1e5
    centre[:, 2] = np.linspace(0.0, 1.0, len(centre)) * (1.0 - np.pi ** 2 / 8e5)
    # the .bp's displaced lines: the mode shapes, 0.1 L at the tip
    for step in steps:
        assert step["points"] == pytest.approx(
            centre + 0.1 * step["point"]["mode_displacement"], abs=1e-9)
    fig = mode_figure(centre, [s["points"] for s in steps],
                      [f"{r['load_factor']:.6g}" for r in rows])
    planes = []
    for ax, step in zip(fig.axes, steps):
        drawn_centre, drawn_mode = (line.get_xydata() for line in ax.lines)
        assert drawn_centre[:, 0] == pytest.approx(0.0, abs=1e-12)     # straight, upright
        assert drawn_centre[:, 1] == pytest.approx(centre[:, 2] - centre[:, 2].mean(),
                                                   abs=1e-12)
        lateral = step["points"][:, :2]
        # drawn sideways distance = the mode's lateral displacement (planar: no loss)
        assert drawn_mode[:, 0] == pytest.approx(            # drawn to the tip's side
            np.linalg.norm(lateral, axis=1), abs=1e-9)
        assert drawn_mode[-1, 0] == pytest.approx(0.1, rel=1e-9)
        assert drawn_mode[:, 1] == pytest.approx(step["points"][:, 2] - centre[:, 2].mean(),
                                                 abs=1e-9)
        assert ax.get_title() == f"{rows[len(planes)]['load_factor']:.6g}"
        planes.append(view_plane(centre, step["points"] - centre)[1])
    assert abs(planes[0] @ planes[1]) < 1e-6          # the two planes, perpendicular


def test_a_systems_rods_are_drawn_apart():
    """Two rods of a system (3 and 4 nodes, parallel, 0.5 apart; the sample's cells skip
    from the first rod's last node to the second's first): each is its own drawn line,
    for the centre line and for the displaced one, and their points are the rods'."""
    from dolfin_rod.output.mode_picture import runs
    s = np.array([0.0, 0.5, 1.0, 0.0, 1 / 3, 2 / 3, 1.0])
    centre = np.column_stack([np.r_[np.zeros(3), np.full(4, 0.5)], np.zeros(7), s])
    segments = np.array([[0, 1], [1, 2], [3, 4], [4, 5], [5, 6]])
    assert [list(r) for r in runs(segments, 7)] == [[0, 1, 2], [3, 4, 5, 6]]
    mode = centre + np.column_stack([np.zeros(7), 0.1 * s, np.zeros(7)])
    ax = mode_figure(centre, [mode], ["mode 1"], segments=segments).axes[0]
    assert [len(line.get_xydata()) for line in ax.lines] == [3, 4, 3, 4]
    plane = view_plane(centre, mode - centre)
    for line, points, rod in zip(ax.lines, [centre, centre, mode, mode], runs(segments, 7) * 2):
        along, across = ((points[rod] - centre.mean(axis=0)) @ plane.T).T
        assert line.get_xydata() == pytest.approx(np.column_stack([across, along]), abs=1e-12)
