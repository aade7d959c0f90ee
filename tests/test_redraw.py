"""Pictures of a finished run drawn again (`dolfin-rod plot RUN [quantities]`,
`RunResult.plot()`) and the VTK XML copy of the fields (rod.pvd + rod/*.vtu, any ParaView),
issue 29 items 1, 4 and 6."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from dolfin_rod import run
from dolfin_rod.cli import main
from dolfin_rod.output import vtk_xml
from dolfin_rod.output.vtk_xml import LineVTU, read_pvd, read_vtu
from dolfin_rod.output.vtx import read_vtx
from quick_scenes import ROOT, quick_scene

SCENES = ROOT / "scenes"
HEIGHT = 340     # px of one row of histories.png: figsize 3.4 in per row at 100 dpi (plots.py)


@pytest.fixture(scope="module")
def cantilever(tmp_path_factory):
    """The bundled gravity cantilever, 8 cells, 5 steps, with its fields."""
    folder = tmp_path_factory.mktemp("redraw") / "run"
    scene = quick_scene(SCENES / "gravity_cantilever.toml", 5, geometry__n_cells=8)
    return run(scene, out=folder, quiet=True)


def test_the_vtu_files_hold_the_rod_bp_steps(cantilever):
    """rod.pvd lists one .vtu per step of rod.bp (outputs.every = 2 of the scene, and the
    last step) with the same times, points, cells and
    fields (both written from the same float64 samples: equal to the bit), and the last
    step's end point is the CSV's tip position (the model's r(L), 1e-12: round-off of
    the evaluation at the vertex)."""
    folder = cantilever.folder
    vtu, bp = read_pvd(folder / "rod.pvd"), read_vtx(folder / "rod.bp")
    times = cantilever.series["time"]
    assert [s["time"] for s in vtu] == [times[k] for k in (0, 2, 4, 5)]  # every = 2, last
    assert len(bp) == len(vtu)
    for a, b in zip(vtu, bp):
        assert a["time"] == b["time"]
        np.testing.assert_array_equal(a["points"], b["points"])
        np.testing.assert_array_equal(a["cells"], b["cells"])
        for kind in ("point", "cell"):
            assert set(a[kind]) == set(b[kind])
            for name in a[kind]:
                np.testing.assert_array_equal(a[kind][name].reshape(np.shape(b[kind][name])),
                                              b[kind][name], err_msg=name)
    last = vtu[-1]
    tip = last["points"][np.argmax(last["point"]["s"])]
    expected = [cantilever.series[f"tip_position_{c}"][-1] for c in "xyz"]
    np.testing.assert_allclose(tip, expected, atol=1e-12)
    files = json.loads((folder / "summary.json").read_text())["files"]
    assert "rod.pvd" in files and "rod/step-00003.vtu" in files


def test_the_series_as_a_table_says_how_to_get_pandas(cantilever, monkeypatch):
    """RunResult.dataframe() without pandas (None in sys.modules makes its import fail,
    as on a system without it): an ImportError that names the install command."""
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"needs pandas.*pip install pandas"):
        cantilever.dataframe()


def test_the_series_as_a_table():
    """With pandas: the DataFrame's columns are the series' columns in their order, and
    its values are theirs (float64: equal to the bit)."""
    pytest.importorskip("pandas")
    from dolfin_rod import RunResult
    series = {"time": [0.0, 0.5, 1.0], "tip_position_x": [0.0, 0.125, 0.5]}
    table = RunResult({"status": "completed"}, series, Path(".")).dataframe()
    assert list(table.columns) == list(series)
    assert all(table[c].tolist() == v for c, v in series.items())


def test_a_vtu_round_trip_and_a_resumed_collection(tmp_path, monkeypatch):
    """Known arrays come back exactly; a resume keeps the steps up to its time and
    replaces the later ones (the .pvd lists only files that exist).  The .pvd is
    rewritten after the first step, then at most every PVD_EVERY seconds and at flush (a
    checkpoint, where a resume starts) and close."""
    points = np.array([[0.0, 0.0, 0.0], [0.1, 0.2, 0.3], [1.0 / 3.0, -2.5e-17, 7.0]])
    d1 = np.arange(9.0).reshape(3, 3) / 7.0
    u = np.array([[1e-300, 2.0, -3.0], [np.pi, 0.0, 1e300]])
    monkeypatch.setattr(vtk_xml, "PVD_EVERY", 1e9)     # (no rewrite after a slow step)
    writer = LineVTU(tmp_path / "rod.pvd")
    for t in (0.0, 0.5, 1.0):
        writer.write(t, points + t, {"s": [0.0, 0.5, 1.0], "d1": d1}, {"u": u, "xi": [1, 2]})
    assert [s["time"] for s in read_pvd(tmp_path / "rod.pvd")] == [0.0]
    writer.flush()
    step = read_vtu(tmp_path / "rod/step-00001.vtu")
    np.testing.assert_array_equal(step["points"], points + 0.5)
    np.testing.assert_array_equal(step["point"]["d1"], d1)
    np.testing.assert_array_equal(step["cell"]["u"], u)
    np.testing.assert_array_equal(step["cells"], [[0, 1], [1, 2]])
    resumed = LineVTU(tmp_path / "rod.pvd", keep_until=0.5)
    resumed.write(0.75, points, {"s": [0.0, 0.5, 1.0]}, {"xi": [3, 4]})
    resumed.close()
    steps = read_pvd(tmp_path / "rod.pvd")
    assert [s["time"] for s in steps] == [0.0, 0.5, 0.75]
    assert sorted(p.name for p in (tmp_path / "rod").iterdir()) == [
        "step-00000.vtu", "step-00001.vtu", "step-00002.vtu"]
    np.testing.assert_array_equal(steps[-1]["cell"]["xi"], [3.0, 4.0])


def test_plot_redraws_chosen_quantities(cantilever, capsys):
    """`dolfin-rod plot RUN tip_deflection reaction_force_start_z`: one row of two panels
    (a panel and a CSV column), and the 3-D pictures again from rod.pvd; the default
    panels of this scene are four (tip deflection, reactions, energy, residual): two rows."""
    folder = cantilever.folder
    (folder / "snapshots.png").unlink()
    assert main(["plot", str(folder), "tip_deflection", "reaction_force_start_z",
                 "--to", str(folder / "two.png")]) == 0
    assert Image.open(folder / "two.png").size == (1100, HEIGHT)
    assert (folder / "snapshots.png").stat().st_size > 10_000
    assert f"wrote {folder / 'animation.gif'}" in capsys.readouterr().out
    written = cantilever.plot()
    assert written[0] == folder / "histories.png"
    assert Image.open(written[0]).size == (1100, 2 * HEIGHT)


def test_plot_refuses_what_it_cannot_draw(cantilever, tmp_path, capsys):
    """A quantity that is neither a panel nor a column, a folder without a run, a --to
    that is not a picture or an existing file outside the run folder: exit 2, one line
    naming it, nothing drawn or replaced."""
    before = (cantilever.folder / "histories.png").stat().st_mtime_ns
    assert main(["plot", str(cantilever.folder), "tip_deflexion"]) == 2
    err = capsys.readouterr().err
    assert "quantities: tip_deflexion is neither a panel" in err and "free_energy" in err
    assert (cantilever.folder / "histories.png").stat().st_mtime_ns == before
    assert main(["plot", str(tmp_path)]) == 2
    assert "no timeseries.csv" in capsys.readouterr().err
    assert main(["plot", str(cantilever.folder), "--color", "w"]) == 2
    # --to never replaces a user's file outside the run folder, and names a picture
    thesis = tmp_path / "thesis.png"
    thesis.write_bytes(b"a user's figure")
    assert main(["plot", str(cantilever.folder), "--to", str(thesis)]) == 2
    assert "--to" in capsys.readouterr().err and thesis.read_bytes() == b"a user's figure"
    assert main(["plot", str(cantilever.folder), "--to", str(tmp_path / "notes.tex")]) == 2
    assert "name a picture file" in capsys.readouterr().err
    assert not (tmp_path / "notes.tex").exists()
    # a damaged time series (binary bytes appended): one line, not a traceback
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    (damaged / "timeseries.csv").write_bytes(
        (cantilever.folder / "timeseries.csv").read_bytes() + bytes(range(128, 256)))
    assert main(["plot", str(damaged)]) == 2
    assert "not a time series of numbers" in capsys.readouterr().err


def test_plot_of_a_torsion_run_draws_its_spacetime(tmp_path):
    """A torsion PDE run (4 cells): the plot command draws its histories and spacetime
    picture from rod.pvd, whose points are s e_3 (s in [0, 1], the dimensionless rod)."""
    scene = quick_scene(SCENES / "torsion_relaxation.toml", 3, geometry__n_cells=4,
                        scene__model="torsion")      # (auto: the homogeneous ODE)
    result = run(scene, out=tmp_path / "run", quiet=True)
    rows = list(csv.DictReader((result.folder / "timeseries.csv").open()))
    steps = read_pvd(result.folder / "rod.pvd")
    assert len(steps) == len(rows)
    np.testing.assert_allclose(steps[0]["points"][:, 2], np.linspace(0, 1, 5), atol=1e-15)
    names = [p.name for p in result.plot()]
    assert names == ["histories.png", "spacetime.png"]


# the last-step bounds (xmin, xmax, ymin, ymax, zmin, zmax) and s range of two full runs
# (read from their rod.pvd): the DNA molecule at its longest (dna_overstretching.toml,
# t = 8.6 s: 169 nm along e_3) and back at 100 nm (t = 17 s), which the fixed tube radius
# and camera of the old script rendered blank; the gravity cantilever at t = 1 s (m)
RUN_BOUNDS = {"dna longest": ((0.0, 0.0, 0.0, 0.0, 0.0, 169.11441), (0.0, 100.0)),
              "dna end": ((0.0, 0.0, 0.0, 0.0, 0.0, 100.0), (0.0, 100.0)),
              "cantilever": ((-0.359182, 0.0, 0.0, 0.0, -0.517436, 0.097584), (0.0, 1.0))}


@pytest.mark.parametrize("run", RUN_BOUNDS)
def test_paraview_screenshot_frames_the_rod_from_its_own_size(run):
    """docs/paraview_screenshot.py's framing (no pvpython needed) against a pinhole camera
    with ParaView's 30 degree view angle and the 900 x 700 px picture: the camera looks
    across the thinnest side of the bounds, the whole rod fits in the picture, it spans
    at least half of it (the script aims at 60 %), and the tube is at least 5 px thick."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("paraview_screenshot",
                                                  ROOT / "docs" / "paraview_screenshot.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    bounds, s_range = RUN_BOUNDS[run]
    frame = script.framing(bounds, s_range)
    extents = np.array(bounds[1::2]) - np.array(bounds[0::2])
    view = np.array(frame["position"]) - np.array(frame["focal_point"])
    distance = np.linalg.norm(view)
    up = np.array(frame["view_up"])
    across = np.cross(view / distance, up)
    assert abs(view @ up) < 1e-12 * distance and extents[np.argmax(np.abs(view))] == extents.min()
    height = 2 * distance * np.tan(np.radians(15.0))          # world size of 700 px
    width = height * 900 / 700
    assert extents @ np.abs(up) <= height and extents @ np.abs(across) <= width
    assert max(extents @ np.abs(up) / height, extents @ np.abs(across) / width) >= 0.5
    assert 2 * frame["tube"] / height * 700 >= 5.0
    assert frame["size"] == max(extents.max(), s_range[1] - s_range[0])
