"""A scene that starts from a previous run's saved state (``[initial] from_run``,
output/from_run.py): creep under a load (run A), then recovery without it (run B from A's
state) against the paper's closed forms and against the one run whose load is removed;
the same on two ranks, a state written on two ranks read by one and the reverse; the
errors that name initial.from_run before any model is built."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import run
from dolfin_rod.cli import main
from dolfin_rod.torsion.closed_forms import creep, creep_exponential, relaxation

ROOT = Path(__file__).resolve().parents[1]
TORSION = ROOT / "scenes" / "torsion_creep.toml"       # alpha 2, alpha_d 1, mu 0.2, mu_d 0.5
ROD = ROOT / "scenes" / "cantilever_creep.toml"        # end force 0.1 e1, dt 0.05
QUIET = {"outputs.plots": False, "outputs.fields": False, "outputs.animation": False,
         "outputs.progress": False}
COMM = MPI.COMM_WORLD


def shared(tmp_path) -> Path:
    return Path(COMM.bcast(str(tmp_path), root=0))


def creep_then_recovery(folder: Path, scene: Path, t1: float, unloaded: dict,
                        comm=None, **overrides) -> tuple:
    """Run A (the scene's load to t1, its end state saved), then run B from A's state
    with the ``unloaded`` loads (and keys) for another t1 (unless they give t_end)."""
    common = {**QUIET, **overrides, "time.t_end": t1}
    a = run(scene, {**common, "outputs.final_checkpoint": True}, out=folder / "A",
            comm=comm, quiet=True)
    b = run(scene, {**common, "initial.from_run": str(folder / "A"), **unloaded},
            out=folder / "B", comm=comm, quiet=True)
    return a, b


def test_recovery_from_a_creep_run_is_the_closed_form(tmp_path):
    """Creep under m0 = 1 to t1 = 0.5 (run A), then the load removed (run B from A's
    state): eqs. twist, nattwist without a load give (u, u_d)(t1 + t) = exp(-tA) (u,
    u_d)(t1), from the closed-form creep state at t1 (closed_forms.creep,
    creep_exponential; docs/corrections.md item 2).  B starts exactly at A's end state,
    and its error against the closed form falls with dt as BDF2's, order 2 with its
    backward-Euler startup step: the ratio for a halved dt tends to 4 (measured 2.8 from
    dt = 0.02 to 0.01, 3.3 from 0.01 to 0.005, as dt times the fast rate 14.6 of A
    shrinks); first order, as the one run through the load's jump is, gives 2."""
    errors = []
    for dt in (0.02, 0.01):
        folder = tmp_path / f"dt{dt}"
        a, b = creep_then_recovery(folder, TORSION, 0.5,
                                   {"loads.end_torsion": {"type": "constant", "value": 0.0}},
                                   **{"scene.model": "torsion", "geometry.n_cells": 2,
                                      "time.dt": dt})
        assert b.summary["from_run"] == {"folder": str(folder / "A"), "time": 0.5,
                                         "step": round(0.5 / dt), "continued": False}
        assert b.summary["end_torsion_impulse_at_0"] is None      # not a start from rest
        for key in ("end_rotation", "mean_natural_twist"):
            assert b.series[key][0] == a.series[key][-1]
        t = np.array(b.series["time"])
        state = creep_exponential(t, 2.0, 1.0, 0.2, 0.5) @ np.array(creep(0.5, 1.0, 2.0, 1.0,
                                                                          0.2, 0.5))
        computed = np.array([b.series["end_rotation"], b.series["mean_natural_twist"]]).T
        errors.append(np.abs(computed - state).max())
    assert errors[1] < 0.01 * np.abs(state).max()
    assert errors[0] / errors[1] > 2.5, errors


def test_a_twisted_rod_released_springs_back_to_its_natural_twist(tmp_path):
    """scenes/twisted_rod_relaxation.toml (3-D rod, quaternions): a quarter turn held for
    t1 = 20 s (run A), then the end released (run B from A's state, no end rotation).
    Homogeneous torsion with A_3, A_d3, M_d3: held, u_d(t1) is the relaxation closed form
    (closed_forms.relaxation); released, the torque A_3 (u - u_d) vanishes at once, so
    the end turns back to L u_d (L u = the tip angle with L u_0 = pi/2), and M_d3 u_d' =
    -A_d3 u_d decays it: angle(t) = u_d(t1) exp(-A_d3 t / M_d3).  The quaternion
    interpolation of the twist (pi/2 over n cells) is second order in the cell size:
    the largest error falls from 1.7e-3 rad at 4 cells to 3.6e-4 at 8 (BDF2 at dt = 0.5,
    rate 1/60: 1e-5)."""
    scene = ROOT / "scenes" / "twisted_rod_relaxation.toml"
    A3, Ad3, Md3 = 0.0009817477042468104, 0.0004908738521234052, 0.029452431127404314
    held, _ = relaxation(20.0, np.pi / 2, A3, Ad3, Md3)
    errors = []
    for n in (4, 8):
        a, b = creep_then_recovery(tmp_path / str(n), scene, 20.0, {
            "boundary.end_rotation": None, "geometry.rotations": "quaternion",
            "time.t_end": 10.0}, **{"geometry.n_cells": n})
        assert b.series["tip_rotation_angle"][0] == a.series["tip_rotation_angle"][-1]
        t = np.array(b.series["time"][1:])
        errors.append(np.abs(np.array(b.series["tip_rotation_angle"][1:])
                             - held * np.exp(-Ad3 / Md3 * t)).max())
    assert errors[1] < 5e-4 and errors[0] / errors[1] > 3.0, errors


@pytest.mark.parametrize("case", ["rod", "dynamic_rod", "uniform_torsion"])
def test_continued_integration_is_the_run_whose_load_is_removed(tmp_path, case):
    """With continue_integration, A then B is the one run C whose load is removed in the
    step after t1 (a table to 0 at t1 + dt/2: the steps sample it at t1 and t1 + dt
    only): the same operations on the same state, equal to round-off (1e-13 of the O(1)
    tip position, energies and twist).  A 3-D quasi-static rod (quaternions, BDF2), the
    dynamic gravity cantilever (rotation vectors, generalized-alpha: its algorithmic
    accelerations carried on, no new start) and the uniform torsion model (its global
    natural twist on a real space)."""
    zero = [0.0, 0.0, 0.0]
    if case == "rod":
        scene, dt, key, value = ROD, 0.05, "loads.end_force", [0.1, 0.0, 0.0]
        overrides, columns = {"geometry.n_cells": 4}, ("tip_position_x", "tip_position_z",
                                                       "free_energy")
    elif case == "dynamic_rod":     # its weight rho A g as a distributed force
        scene, dt = ROOT / "scenes" / "gravity_cantilever.toml", 0.01
        key, value = "loads.distributed_force", [-1000.0 * np.pi * 0.025**2 * 9.81, 0.0, 0.0]
        overrides = {"geometry.n_cells": 4, "loads.gravity": zero,
                     key: {"type": "constant", "value": value}}
        columns = ("tip_position_x", "kinetic_energy", "free_energy")
    else:
        scene, dt, key, value = TORSION, 0.02, "loads.end_torsion", 1.0
        overrides = {"scene.model": "torsion", "material.variant": "uniform",
                     "geometry.n_cells": 2, "time.dt": dt}
        columns, zero = ("end_rotation", "mean_natural_twist"), 0.0
    t1 = 4 * dt
    a, b = creep_then_recovery(tmp_path, scene, t1, {key: {"type": "constant", "value": zero},
                                                     "initial.continue_integration": True},
                               **overrides)
    assert b.summary["from_run"]["continued"]
    c = run(scene, {**QUIET, **overrides, "time.t_end": 2 * t1, key: {
        "type": "table", "times": [0.0, t1, t1 + dt / 2], "values": [value, value, zero]}},
        out=tmp_path / "C", quiet=True)
    for column in columns:
        np.testing.assert_allclose(b.series[column], c.series[column][4:], rtol=0, atol=1e-13,
                                   err_msg=column)
        assert abs(c.series[column][4] - a.series[column][0]) > 1e-4   # the load acted


def test_from_time_picks_a_kept_state(tmp_path):
    """keep_checkpoints keeps every state: from_time = 0.1 starts at A's row at 0.1, the
    default at its last one (0.2)."""
    common = {**QUIET, "geometry.n_cells": 4, "time.t_end": 0.2}
    a = run(ROD, {**common, "outputs.checkpoint_every": 2, "outputs.keep_checkpoints": True},
            out=tmp_path / "A", quiet=True)
    for at, row in ((0.1, 2), (None, 4)):
        given = {} if at is None else {"initial.from_time": at}
        b = run(ROD, {**common, "time.t_end": 0.05, "initial.from_run": str(tmp_path / "A"),
                      **given}, out=tmp_path / f"B{at}", quiet=True)
        assert b.summary["from_run"]["step"] == row
        for column in ("tip_position_x", "tip_position_z"):
            assert b.series[column][0] == a.series[column][row]


UNLOADED = {"loads.end_force": {"type": "constant", "value": [0.0, 0.0, 0.0]},
            "initial.continue_integration": True}
SMALL = {**QUIET, "geometry.n_cells": 4, "time.t_end": 0.2}


def serial_recovery(folder: str, source: str, out: str) -> list[float]:
    """(On one process, serial_reference) run A into folder/source unless it is there,
    then B from it into folder/out; B's tip positions."""
    folder_path = Path(folder)
    if not (folder_path / source).exists():
        run(ROD, {**SMALL, "outputs.final_checkpoint": True}, out=folder_path / source,
            quiet=True)
    b = run(ROD, {**SMALL, **UNLOADED, "initial.from_run": str(folder_path / source)},
            out=folder_path / out, quiet=True)
    return b.series["tip_position_x"]


@pytest.mark.mpi
def test_a_state_saved_on_two_ranks_starts_a_serial_run_and_the_reverse(tmp_path):
    """Creep then recovery on two ranks = on one process (1e-10: another summation
    order); a state written on two ranks read by one process, and one written by one
    process (the serial A) read by two ranks, give the same B."""
    from serial_reference import on_one_process
    folder = shared(tmp_path)
    _, b = creep_then_recovery(folder / "parallel", ROD, 0.2, UNLOADED,
                               **{"geometry.n_cells": 4})
    serial = parallel_read = None
    if COMM.rank == 0:
        serial = on_one_process("test_from_run.serial_recovery", str(folder), "serial/A",
                                "serial/B")
        parallel_read = on_one_process("test_from_run.serial_recovery", str(folder),
                                       "parallel/A", "B_serial_from_parallel")
    COMM.barrier()
    reverse = run(ROD, {**SMALL, **UNLOADED, "initial.from_run": str(folder / "serial" / "A")},
                  out=folder / "B_parallel_from_serial", quiet=True)
    if COMM.rank == 0:
        for other in (serial, parallel_read, reverse.series["tip_position_x"]):
            np.testing.assert_allclose(other, b.series["tip_position_x"], rtol=1e-10,
                                       atol=1e-14)


@pytest.fixture(scope="module")
def saved_rod_run(tmp_path_factory) -> Path:
    """A short creep run of the cantilever with its end state saved, and a run without."""
    folder = Path(COMM.bcast(str(tmp_path_factory.mktemp("from_run")), root=0))
    common = {**QUIET, "geometry.n_cells": 4, "time.t_end": 0.1}
    run(ROD, {**common, "outputs.final_checkpoint": True}, out=folder / "A", quiet=True)
    run(ROD, common, out=folder / "unsaved", quiet=True)
    return folder


@pytest.mark.parametrize("sets, key, words", [
    (["initial.from_run=nowhere"], "initial.from_run", "nowhere: not a run folder"),
    (["initial.from_run={A}", "geometry.n_cells=8"], "initial.from_run",
     "another geometry.n_cells (4 there, 8 here)"),
    (["initial.from_run={A}", "material.variant=uniform", "geometry.n_cells=4"],
     "initial.from_run", "another material.variant ('local' there, 'uniform' here)"),
    (["initial.from_run={unsaved}", "geometry.n_cells=4"], "initial.from_run",
     "the run saved no state"),
    (["initial.from_run={A}", "geometry.n_cells=4", "initial.from_time=0.05"],
     "initial.from_time", "saved no state at t = 0.05 (it has t = 0.1"),
    (["initial.from_run={A}", "geometry.n_cells=4", "time.dt=0.025",
      "initial.continue_integration=true"], "initial.continue_integration",
     "time.dt = 0.05, this scene has 0.025"),
    (["initial.from_run={A}", "initial.natural_curvature=[0, 0, 0]"],
     "initial.natural_curvature", "not with initial.from_run"),
    (["initial.from_time=0.1"], "initial.from_time", "give initial.from_run too"),
])
def test_a_bad_start_names_its_key_and_exits_2(saved_rod_run, capsys, sets, key, words):
    """Exit 2 with one line naming the key and what differs, before any model is built
    (no run folder is left)."""
    out = saved_rod_run / f"bad-{abs(hash(tuple(sets)))}"
    argv = ["run", str(ROD), "--out", str(out), "--quiet"]
    for item in sets:
        argv += ["--set", item.format(A=saved_rod_run / "A", unsaved=saved_rod_run / "unsaved")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    if COMM.rank == 0:
        assert len(err.splitlines()) == 1 and f"[{key}]" in err and words in err, err
        assert not out.exists()


def test_out_that_holds_the_saved_state_is_refused_and_the_state_kept(saved_rod_run, capsys):
    """--out the previous run's folder (or its parent) with --overwrite: exit 2 naming
    initial.from_run before the folder is prepared; the saved state is still there (it
    was deleted, and the run failed with a traceback reading it)."""
    source = saved_rod_run / "A"
    before = sorted(p.name for p in source.iterdir()) if COMM.rank == 0 else None
    for out in (source, saved_rod_run):
        assert main(["run", str(ROD), "--quiet", "--overwrite", "--out", str(out),
                     "--set", f"initial.from_run={source}",
                     "--set", "geometry.n_cells=4"]) == 2
        err = capsys.readouterr().err
        if COMM.rank == 0:
            assert "[initial.from_run]" in err and "another folder" in err, err
            assert sorted(p.name for p in source.iterdir()) == before


def test_a_torsion_state_does_not_start_a_rod(saved_rod_run, capsys):
    """Another model kind: a torsion run's state offered to a 3-D rod scene."""
    folder = saved_rod_run
    run(TORSION, {**QUIET, "scene.model": "torsion", "geometry.n_cells": 2, "time.t_end": 0.02,
                  "outputs.final_checkpoint": True}, out=folder / "torsion", quiet=True)
    assert main(["run", str(ROD), "--quiet", "--set", f"initial.from_run={folder / 'torsion'}",
                 "--out", str(folder / "bad-model")]) == 2
    assert "another model ('torsion' there, 'rod' here)" in capsys.readouterr().err


def test_check_names_the_state_or_the_difference(saved_rod_run, capsys):
    """``dolfin-rod check`` reads the saved state as a run would (no model built): the
    state it starts from, a folder not there yet (a second stage before its first), or
    exit 2 naming the difference."""
    good = ["check", str(ROD), "--set", "geometry.n_cells=4"]
    assert main(good + ["--set", f"initial.from_run={saved_rod_run / 'A'}"]) == 0
    out = capsys.readouterr().out
    assert f"starts from: {saved_rod_run / 'A'}, its state at t = 0.1 (step 2)" in out
    assert main(good + ["--set", f"initial.from_run={saved_rod_run / 'later'}"]) == 0
    assert "not there yet: run the scene that writes it first" in capsys.readouterr().out
    assert main(["check", str(ROD), "--set", f"initial.from_run={saved_rod_run / 'A'}"]) == 2
    assert "another geometry.n_cells (4 there, 8 here)" in capsys.readouterr().err


@pytest.mark.parametrize("key", ["outputs.final_checkpoint", "outputs.checkpoint_every",
                                 "initial.from_run"])
def test_the_ode_model_saves_and_reads_no_state(tmp_path, capsys, key):
    """The homogeneous-torsion ODE is solved as a whole: a checkpoint of it (an
    IndexError of the checkpoint writer before) or a start from a state is exit 2 naming
    the key and the way out (scene.model = "torsion")."""
    value = {"outputs.final_checkpoint": "true", "outputs.checkpoint_every": "2",
             "initial.from_run": str(tmp_path)}[key]
    assert main(["run", str(TORSION), "--quiet", "--set", f"{key}={value}", "--out",
                 str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert f"[{key}]: the 'ode' model" in err and 'scene.model = "torsion"' in err


PULLED = """
[scene]
name = "pulled"
[geometry]
n_cells = 4
[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 1.0], B = [100.0, 100.0, 100.0] }
[boundary]
start = "clamped"
end = "free"
end_displacement = { type = "ramp", value = [0.3, 0.0, -0.1], duration = 0.2 }
[time]
t_end = 0.2
dt = 0.05
"""


def test_a_support_holds_the_end_where_the_state_has_it(tmp_path):
    """Pre-stress: run A pulls the free end of a clamped elastic rod to (0.3, 0, 0.9)
    (end_displacement), then B from its state pins that end (boundary.end = "pinned", no
    displacement): the pin holds the end where A left it, so the equilibrium stays
    (1e-9: Newton's tolerance on an O(1) state); a support at the stress-free end would
    pull the end back by 0.32."""
    scene = tmp_path / "pulled.toml"
    scene.write_text(PULLED)
    a = run(scene, {**QUIET, "outputs.final_checkpoint": True}, out=tmp_path / "A",
            quiet=True)
    b = run(scene, {**QUIET, "boundary.end": "pinned", "boundary.end_displacement": None,
                    "initial.from_run": str(tmp_path / "A")}, out=tmp_path / "B", quiet=True)
    for column, value in (("tip_position_x", 0.3), ("tip_position_z", 0.9)):
        assert a.series[column][-1] == pytest.approx(value, abs=1e-12)
        np.testing.assert_allclose(b.series[column], value, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.series["free_energy"], a.series["free_energy"][-1],
                               rtol=1e-9)


def test_load_state_puts_a_model_built_in_python_in_a_saved_state(saved_rod_run):
    """dolfin_rod.load_state (the Python API of a model without a scene run): the
    cantilever's model built from its scene without the load, put in A's saved end
    state, has A's last row; stepped by TimeStepper without the load it moves back
    towards the straight rod (as B of the scene would); a folder without a state, a
    model of another layout: ValueError."""
    from dolfin_rod import TimeStepper, build, load_scene, load_state
    scene = load_scene(ROD, {**QUIET, "geometry.n_cells": 4, "loads.end_force": None})
    sim = build(scene, "rod")
    sim.start()
    model = sim.model
    assert load_state(model, saved_rod_run / "A") == pytest.approx(0.1)
    a = np.genfromtxt(saved_rod_run / "A" / "timeseries.csv", delimiter=",", names=True)
    start = model.diagnostics(0.0)
    for column in ("tip_position_x", "tip_position_z", "free_energy"):
        assert start[column] == pytest.approx(a[column][-1], rel=1e-14, abs=1e-15)
    TimeStepper(model.problem, scheme="bdf2").run(0.0, 0.1, 0.05)
    assert 0.0 < model.diagnostics(0.1)["tip_position_x"] < start["tip_position_x"]
    with pytest.raises(ValueError, match="the run saved no state"):
        load_state(model, saved_rod_run / "unsaved")
    other = build(load_scene(ROD, {**QUIET, "geometry.n_cells": 6}), "rod")
    other.start()
    with pytest.raises(ValueError, match="its state has .* values of field_0, this model"):
        load_state(other.model, saved_rod_run / "A")


def test_a_run_started_from_a_state_resumes_as_it_began(saved_rod_run):
    """A run from a saved state, stopped and resumed (--resume), is the uninterrupted
    one (1e-12, resume's round-off) and its summary still says where it started (the
    checkpoint keeps it)."""
    common = {**QUIET, "geometry.n_cells": 4, "time.t_end": 0.25, "loads.end_force": None,
              "initial.from_run": str(saved_rod_run / "A"), "outputs.checkpoint_every": 2}
    full = run(ROD, common, out=saved_rod_run / "resumed-full", quiet=True)
    part = run(ROD, common, out=saved_rod_run / "resumed", quiet=True, stop_after=3)
    assert part.status == "stopped"
    resumed = run(ROD, common, out=saved_rod_run / "resumed", quiet=True, resume=True)
    assert resumed.summary["from_run"] == full.summary["from_run"] == {
        "folder": str(saved_rod_run / "A"), "time": 0.1, "step": 2, "continued": False}
    np.testing.assert_allclose(resumed.series["tip_position_x"], full.series["tip_position_x"],
                               rtol=0, atol=1e-12)
