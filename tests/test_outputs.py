"""Run outputs a person looks at: rod.bp (read back with the adios2 Python bindings),
animation and pictures, summary file list, CSV format, ParaView history after resume.

Tolerances
* rod.bp geometry vs the model's own displacement dofs after the same steps: the same
  doubles go through a different path (UFL expression at the vertices vs dof values),
  so they agree to round-off: 1e-12 on O(1) coordinates.
* static equilibrium (quasi-static cantilever with an end force P): with P1 positions
  and the 1-point Gauss rule the displacement equations read sum_cells (R n)_c . dx'_c
  h = P . dx(L), so the spatial contact force R n of every cell is exactly P up to
  Newton's residual tolerance (atol 1e-10 on loads of 0.1): 1e-8 absolute.
* torsion with an applied end torsion m0 (quasi-static): the same argument for
  int m eta' ds = m0 eta(1) with P1 eta: m = m0 in every cell to 1e-8.
* 2 ranks vs 1: the same equations solved to Newton's tolerance (snes_rtol 1e-10, stol
  1e-10 relative): displacements O(1) agree to 1e-8.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import run_scene
from dolfin_rod.scenes import build
from dolfin_rod.output.vtx import read_vtx
from quick_scenes import ROOT, quick_scene, run_serially

GRAVITY = ROOT / "scenes/gravity_cantilever.toml"
CANTILEVER = ROOT / "scenes/cantilever_creep.toml"
comm = MPI.COMM_WORLD


def shared(tmp_path) -> Path:
    return Path(comm.bcast(str(tmp_path), root=0))


def centre_line_by_api(scene, steps: int) -> np.ndarray:
    """X + x at the vertices after ``steps`` steps of the same scene through the Python
    API (dof values, gathered and sorted by s): the reference for rod.bp."""
    sim = build(scene, "rod")
    sim.start()
    dt = scene["time"]["dt"]
    for k in range(1, steps + 1):
        sim.advance((k - 1) * dt, k * dt)
    x = sim.model.f["displacement"]
    V = x.function_space
    n = V.dofmap.index_map.size_local
    s = V.tabulate_dof_coordinates()[:n, 0]
    values = x.x.array.reshape(-1, 3)[:n]
    gathered = comm.gather((s, values), root=0)
    if comm.rank != 0:
        return None
    s = np.concatenate([g[0] for g in gathered])
    values = np.concatenate([g[1] for g in gathered])
    order = np.argsort(s)
    return values[order] + np.column_stack([0 * s, 0 * s, s])[order]


@pytest.mark.mpi
def test_paraview_file_is_the_deformed_rod(tmp_path):
    """rod.bp's points: the reference line s e_3 at t = 0 and the final centre line (tip
    included) at the last step, serially and on 2 ranks."""
    steps, n = 6, 8
    scene = quick_scene(GRAVITY, steps, geometry__n_cells=n, outputs__every=1,
                        outputs__animation=False, outputs__plots=False)
    folder = shared(tmp_path) / "run"
    summary = run_scene(scene, folder, quiet=True)
    reference = centre_line_by_api(scene, steps)
    if comm.rank != 0:
        return
    assert summary["status"] == "completed"
    data = read_vtx(folder / "rod.bp")
    assert [round(d["time"] / 0.01) for d in data] == list(range(steps + 1))
    s = np.linspace(0.0, 1.0, n + 1)
    assert np.allclose(data[0]["points"], np.column_stack([0 * s, 0 * s, s]), atol=1e-14)
    assert np.allclose(data[-1]["points"], reference, atol=1e-12)
    tip = [summary["final"][f"tip_position_{c}"] for c in "xyz"]
    assert np.allclose(data[-1]["points"][-1], tip, atol=1e-12)
    assert data[-1]["points"][-1, 0] < -1e-3          # it droops along gravity (-x)
    assert np.allclose(data[0]["point"]["s"], s, atol=1e-14)


def test_paraview_fields_a_mechanician_reads(tmp_path):
    """Names, directors orthonormal, reference state at t = 0, statics at the end."""
    scene = quick_scene(CANTILEVER, 3, outputs__animation=False, outputs__plots=False)
    folder = shared(tmp_path) / "run"
    run_scene(scene, folder, quiet=True)
    data = read_vtx(folder / "rod.bp")
    first, last = data[0], data[-1]
    assert set(first["point"]) == {"s", "d1", "d2", "d3"}
    assert set(first["cell"]) == {"u", "v", "u_d", "v_d", "u_ref", "v_ref", "n", "m",
                                  "n_spatial", "m_spatial", "xi"}
    assert np.allclose(np.stack([first["point"][f"d{i}"] for i in (1, 2, 3)], axis=1),
                       np.eye(3), atol=1e-14)                          # R = I at rest
    assert np.allclose(first["cell"]["v"], [0.0, 0.0, 1.0], atol=1e-14)
    assert np.allclose(first["cell"]["u"], 0.0, atol=1e-14)
    for step in data:                                                  # R orthonormal
        D = np.stack([step["point"][f"d{i}"] for i in (1, 2, 3)], axis=2)
        assert np.allclose(np.einsum("nki,nkj->nij", D, D), np.eye(3), atol=1e-12)
    # statics of a cantilever with the end force P = (0.1, 0, 0): R n = P in every cell
    assert np.allclose(last["cell"]["n_spatial"], [0.1, 0.0, 0.0], atol=1e-8)
    assert np.all(last["cell"]["xi"] >= 0.0)                           # local variant
    assert np.abs(last["cell"]["u_d"] - last["cell"]["u_ref"]).max() > 1e-3   # it crept


@pytest.mark.mpi
def test_torsion_paraview_and_spacetime(tmp_path):
    """Torsion: phi at the vertices on the line s e_3, u = phi_s, m = m0 (statics)."""
    from test_scenes import _case
    scene = _case("creep_kelvin_voigt", scene__model="torsion", time__t_end=0.05)
    folder = shared(tmp_path) / "run"
    run_scene(scene, folder, quiet=True)
    if comm.rank != 0:
        return
    data = read_vtx(folder / "rod.bp")
    assert (folder / "spacetime.png").stat().st_size > 10_000
    s = np.linspace(0.0, 1.0, 5)
    for step in data:
        assert np.allclose(step["points"], np.column_stack([0 * s, 0 * s, s]), atol=1e-14)
        phi = step["point"]["phi"]
        assert np.allclose(step["cell"]["u"], np.diff(phi) / 0.25, atol=1e-12)
    assert np.allclose(data[-1]["cell"]["m"], 1.0, atol=1e-8)


@pytest.mark.mpi
def test_resume_appends_to_the_paraview_history(tmp_path):
    """Issue 13 item 4: after --resume rod.bp holds the whole history, not the resumed
    part only, and equals the uninterrupted run's."""
    from test_scenes import _case
    folder = shared(tmp_path)
    scene = _case("relaxation_kelvin_voigt_uniform", scene__model="torsion",
                  outputs__checkpoint_every=3, outputs__plots=False, time__t_end=0.08)
    run_scene(scene, folder / "full", quiet=True)
    run_scene(scene, folder / "part", stop_after=5, quiet=True)
    resumed = run_scene(scene, folder / "part", resume=True, quiet=True)
    if comm.rank != 0:
        return
    assert resumed["status"] == "completed"
    full, part = read_vtx(folder / "full/rod.bp"), read_vtx(folder / "part/rod.bp")
    assert [d["time"] for d in part] == pytest.approx([d["time"] for d in full], abs=1e-15)
    for a, b in zip(full, part):
        assert np.allclose(a["point"]["phi"], b["point"]["phi"], atol=1e-12)
    assert (folder / "part/spacetime.png").exists()


@pytest.mark.mpi
def test_two_ranks_write_the_serial_files(tmp_path):
    """The gravity cantilever on 2 ranks: rod.bp and the CSV as a serial run's."""
    if comm.size == 1:
        pytest.skip("compares an MPI run with a serial one")
    folder = shared(tmp_path)
    kw = dict(geometry__n_cells=8, outputs__every=1, outputs__plots=False)
    scene = quick_scene(GRAVITY, 4, **kw)
    run_scene(scene, folder / "mpi", quiet=True)
    if comm.rank == 0:
        assert run_serially(GRAVITY, folder / "serial", 4, **kw) == "completed"
        a, b = read_vtx(folder / "mpi/rod.bp"), read_vtx(folder / "serial/rod.bp")
        assert len(a) == len(b) == 5
        for x, y in zip(a, b):
            assert np.allclose(x["points"], y["points"], atol=1e-8)
            for name in x["cell"]:
                assert np.allclose(x["cell"][name], y["cell"][name], atol=1e-8), name
        for name in ("animation.gif", "snapshots.png"):
            assert (folder / "mpi" / name).exists()


def test_animation_and_pictures(tmp_path):
    from PIL import Image
    folder = shared(tmp_path)
    run_scene(quick_scene(GRAVITY, 4, geometry__n_cells=8, outputs__every=1), folder / "on",
              quiet=True)
    if comm.rank == 0:
        gif = Image.open(folder / "on/animation.gif")
        assert gif.n_frames == 5 and gif.size[0] >= 800     # readable (issue 29)
        assert (folder / "on/snapshots.png").stat().st_size > 10_000
    off = quick_scene(GRAVITY, 2, geometry__n_cells=4, outputs__animation=False)
    run_scene(off, folder / "off", quiet=True)
    if comm.rank == 0:
        assert not any((folder / "off" / n).exists() for n in ("animation.gif",
                                                               "snapshots.png"))


def _walk(folder: Path) -> list[str]:
    """Every file under folder by os.walk, a *.bp folder as one entry."""
    out = []
    for here, dirs, files in os.walk(folder):
        rel = Path(here).relative_to(folder)
        for d in list(dirs):
            if d.endswith(".bp"):
                out.append(str(rel / d))
                dirs.remove(d)
        out += [str(rel / f) for f in files]
    return sorted(os.path.normpath(p) for p in out)


def test_summary_lists_every_file_and_csv_is_plain(tmp_path):
    folder = shared(tmp_path) / "run"
    run_scene(quick_scene(CANTILEVER, 2), folder, quiet=True)
    if comm.rank != 0:
        return
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["files"] == _walk(folder)
    assert {"rod.bp", "animation.gif", "timeseries.csv", "summary.json"} <= set(summary["files"])
    raw = (folder / "timeseries.csv").read_bytes()
    assert b"\r" not in raw                                   # LF line ends
    header, row0 = raw.decode().splitlines()[:2]
    assert "nan" not in row0.lower()
    fields = dict(zip(header.split(","), row0.split(",")))
    assert fields["power_residual"] == ""                     # no interval before t = 0
