"""The command line, run as a user would: ``python -m dolfin_rod check|run`` in a subprocess.

The bundled scenes are run with a short t_end (rewritten in a copy); their numbers are
compared to closed_forms: the ODE model evaluates the same closed forms (1e-12), the
torsion PDE with BDF2, dt = 0.01 is O(dt^2) accurate (5e-3 on O(1) values).
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dolfin_rod import closed_forms
from test_scenes import relaxation_rederived

ROOT = Path(__file__).resolve().parents[1]


# s: a hang ends the test; a first 3-D rod run on a cold FFCx cache compiles its kernels
# for ~125 s idle (the CLI's own notice), and a compile killed by a shorter timeout
# leaves FFCx's lock behind, which fails every later run of those kernels
CLI_TIMEOUT = 600


def cli(*args, mpi: int = 0, timeout: float = CLI_TIMEOUT) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "dolfin_rod", *map(str, args)]
    if mpi:
        cmd = [shutil.which("mpirun") or "mpirun", "-n", str(mpi), *cmd]
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env)


def short_copy(tmp_path: Path, name: str, t_end: float) -> Path:
    text = (ROOT / "scenes" / name).read_text()
    text = re.sub(r"(?m)^t_end = .*$", f"t_end = {t_end}", text)
    path = tmp_path / name
    path.write_text(text)
    return path


def read_csv(path: Path) -> dict[str, np.ndarray]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k in rows[0]}


@pytest.mark.parametrize("name", ["torsion_relaxation.toml", "torsion_creep.toml"])
def test_check_prints_model_and_reason(name):
    out = cli("check", ROOT / "scenes" / name)
    assert out.returncode == 0, out.stderr
    assert "model: ode" in out.stdout and "why: quasi-static" in out.stdout


def test_help_and_usage_errors_end_before_mpi_init():
    """``--help``, ``--version`` and a usage error are answered before MPI_Init (0.15-0.2 s
    of their time, issue 30): MPI stays uninitialised, the exit statuses are argparse's."""
    code = ("import sys; from dolfin_rod.cli import main\n"
            "for argv in (['--help'], ['--version'], ['run', '--help'], ['no-such']):\n"
            "    try:\n"
            "        main(argv)\n"
            "    except SystemExit as done:\n"
            "        print('status', done.code, file=sys.stderr)\n"
            "print('mpi4py.MPI' in sys.modules, file=sys.stderr)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=CLI_TIMEOUT, cwd=ROOT)
    assert out.stderr.split("\n")[-2] == "False", out.stderr
    assert re.findall(r"status (\d)", out.stderr) == ["0", "0", "0", "2"], out.stderr
    assert "usage: dolfin-rod" in out.stdout and "dolfin-rod 0." in out.stdout


def test_bad_scene_exits_2_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[material]\nalpha = -1.0\n[time]\nt_end = 1.0\ndt = 0.1\n")
    for command in ("check", "run"):
        out = cli(command, bad)
        assert out.returncode == 2
        assert "Traceback" not in out.stderr
        assert out.stderr.strip() == f"error: {bad}: [material.alpha]: must be > 0, got -1"


def test_run_relaxation_matches_closed_form(tmp_path):
    scene = short_copy(tmp_path, "torsion_relaxation.toml", 0.3)
    out = cli("run", scene, "--out", tmp_path / "run")
    assert out.returncode == 0, out.stderr
    run = tmp_path / "run"
    for name in ("scene.toml", "timeseries.csv", "timeseries.json", "summary.json",
                 "timings.json", "histories.png"):
        assert (run / name).exists(), name
    assert (run / "scene.toml").read_text() == scene.read_text()
    s = read_csv(run / "timeseries.csv")
    ud, m = relaxation_rederived(s["time"], 0.5, 2.0, 1.0, 0.5)
    # the exponential of the closed form vs this one: round-off, 1e-12 on O(1) values
    assert np.allclose(s["end_torsion"], m, atol=1e-12, rtol=0)
    assert np.allclose(s["mean_natural_twist"], ud, atol=1e-12, rtol=0)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["model"] == "ode" and summary["status"] == "completed"
    assert "closed_forms.relaxation" in summary["method"]
    series = json.loads((run / "timeseries.json").read_text())
    assert len(series["time"]) == 31


def test_run_creep_with_the_pde(tmp_path):
    scene = short_copy(tmp_path, "torsion_creep.toml", 0.1)
    scene.write_text(scene.read_text().replace("[scene]", '[scene]\nmodel = "torsion"'))
    out = cli("run", scene, "--out", tmp_path / "run", "--set", "outputs.plots=false")
    assert out.returncode == 0, out.stderr
    assert "model: torsion (forced" in out.stdout
    run = tmp_path / "run"
    assert (run / "rod.bp").is_dir()
    s = read_csv(run / "timeseries.csv")
    u, ud = closed_forms.creep(s["time"], 1.0, 2.0, 1.0, 0.2, 0.5)
    assert np.allclose(s["end_rotation"], u, atol=5e-3, rtol=0)
    assert np.allclose(s["mean_natural_twist"], ud, atol=5e-3, rtol=0)


def test_run_under_mpirun_rank0_writes(tmp_path):
    scene = short_copy(tmp_path, "torsion_creep.toml", 0.05)
    scene.write_text(scene.read_text().replace("[scene]", '[scene]\nmodel = "torsion"'))
    # no plots (test_outputs.py draws pictures under mpirun)
    out = cli("run", scene, "--out", tmp_path / "run", "--set", "outputs.plots=false", mpi=2)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("completed:") == 1 and out.stdout.count("model: torsion") == 1
    s = read_csv(tmp_path / "run" / "timeseries.csv")
    assert len(s["time"]) == 6
    u, _ = closed_forms.creep(s["time"], 1.0, 2.0, 1.0, 0.2, 0.5)
    assert np.allclose(s["end_rotation"], u, atol=5e-3, rtol=0)


def test_run_cantilever_rod(tmp_path):
    """3-D rod creep under a small step tip force F = 1e-3 against the exact creep curve.

    Linear (rotations ~F L^2/A = 1e-3 rad: geometric terms ~1e-6 relative) and
    statically determinate: with the 1-point rule each element's moment is F (L - s_e)
    and its shear force F, so curvature and shear strain each follow the scalar creep law
    of eqs. twist/nattwist (mu = M = 0: closed_forms.creep_inviscid) and, by
    complementary energy (tests/test_rod.py, Timoshenko test),
        delta(t) = F L^3/3 (1 - 1/(4 N^2)) c_bend(t) + F L c_shear(t),
    c_bend with (A, A_d, M_d) = (1, 1, 1), c_shear with (B, B_d, N_d) = (100, 100, 1).
    BDF2 at dt = 0.05: the error must fall at second order between dt = 0.05 and 0.025
    (observed order >= 1.8) over t in [0.5, 1] (after the shear creep, rate 100, has
    relaxed, and the BE start-up's transient has decayed), and at dt = 0.05 be below
    1e-3 relative (BDF2's (lambda dt)^2/(3e) = 3e-4 of the bending creep amplitude plus
    the BE start's O(dt^2) share; measured 6.3e-4)."""
    errors = []
    for dt in (0.05, 0.025):
        scene = short_copy(tmp_path, "cantilever_creep.toml", 1.0)
        scene.write_text(re.sub(r"(?m)^dt = .*$", f"dt = {dt}", scene.read_text())
                         .replace("value = [0.1, 0.0, 0.0]", "value = [0.001, 0.0, 0.0]"))
        run = tmp_path / f"run-{dt}"
        # no pictures (half of such a run's time; test_outputs.py and test_drawing.py
        # check them), rod.bp of the finer run only
        out = cli("run", scene, "--out", run, "--set", "outputs.animation=false",
                  "--set", "outputs.plots=false", "--set", f"outputs.fields={dt < 0.05}".lower())
        assert out.returncode == 0 and "model: rod" in out.stdout, out.stdout + out.stderr
        s = read_csv(run / "timeseries.csv")
        t = s["time"]
        bend, _ = closed_forms.creep_inviscid(t, 1.0, 1.0, 1.0, 1.0)
        shear, _ = closed_forms.creep_inviscid(t, 1.0, 100.0, 100.0, 1.0)
        exact = 1e-3 / 3 * (1 - 1 / (4 * 8**2)) * bend + 1e-3 * shear
        late = t >= 0.5 - 1e-12
        errors.append(np.max(np.abs(s["tip_position_x"][late] / exact[late] - 1)))
    assert errors[0] < 1e-3 and np.log2(errors[0] / errors[1]) > 1.8, errors
    assert (tmp_path / "run-0.025" / "rod.bp").is_dir()


def test_set_changes_keys_and_outputs_every_the_frames_written(tmp_path):
    """`run SCENE --set table.key=value` (TOML values, a bare word a string): the gravity
    cantilever for 5 steps of dt = 0.01, 8 cells, fields every 3 steps: rod.pvd holds the
    steps 0, 3 and the last, 5 (the scene's every = 2 would give 0, 2, 4, 5), and the run
    folder's scene.toml is the scene as run (pictures off: test_outputs.py draws them).
    The Python API's override of a Scene object, outputs.every = 1: all 6.  A malformed
    --set or a bad value: exit 2 naming it, nothing run."""
    from dolfin_rod import read_pvd, run
    from dolfin_rod.scenes import load_scene
    out = cli("run", "scenes/gravity_cantilever.toml", "--out", tmp_path / "cli", "--quiet",
              "--set", "time.t_end=0.05", "--set", "geometry.n_cells=8",
              "--set", "outputs.every=3", "--set", "outputs.color=v_d",
              "--set", "outputs.animation=false", "--set", "outputs.plots=false")
    assert out.returncode == 0, out.stderr
    times = [step["time"] for step in read_pvd(tmp_path / "cli" / "rod.pvd")]
    assert times == pytest.approx([0.0, 0.03, 0.05], abs=1e-12)
    as_run = load_scene(tmp_path / "cli" / "scene.toml")
    assert (as_run["outputs"]["every"], as_run["outputs"]["color"]) == (3, "v_d")
    result = run(as_run, {"outputs.every": 1},
                 out=tmp_path / "api", quiet=True)
    assert len(read_pvd(result.folder / "rod.pvd")) == 6
    for bad, says in ((["--set", "outputs.every"], "give TABLE.KEY=VALUE"),
                      (["--set", "outputs.every=0"], "outputs.every")):
        out = cli("run", "scenes/gravity_cantilever.toml", "--out", tmp_path / "bad", *bad)
        assert out.returncode == 2 and says in out.stderr, out.stderr
        assert "Traceback" not in out.stderr and not (tmp_path / "bad").exists()


def test_set_reaches_a_key_of_an_inline_table_and_refuses_an_array_of_tables():
    """--set loads.end_force.value=... changes that key of the inline table (was "unknown
    key" in [loads]); a key of [[joints]] or [[rods]] cannot be overridden (was ignored
    silently: --set joints.kind=ball checked OK and ran the rigid joint), nor a key inside
    a number."""
    from dolfin_rod.scenes import SceneError, load_scene
    scene = load_scene(ROOT / "scenes/buckled_column.toml",
                       {"loads.end_force.value": [0.0, 0.0, -1.0]})
    assert scene["loads"]["end_force"].value == (0.0, 0.0, -1.0)
    assert scene["loads"]["end_force"].duration == 1.0           # the rest of it kept
    for name, says in (("joints.kind", "joints is an array of tables"),
                       ("rods.name", "rods is an array of tables"),
                       ("time.dt.x", "time.dt is not a table")):
        with pytest.raises(SceneError, match=rf"\[{name}\]: override '{name}': {says}"):
            load_scene(ROOT / "scenes/frame.toml", {name: "ball"})


def test_interrupted_run_keeps_what_it_computed(tmp_path):
    """SIGINT mid-run: exit 130, the CSV holds every step up to the interruption and the
    JSON files are written with status 'interrupted'."""
    import signal
    import time
    scene = short_copy(tmp_path, "torsion_creep.toml", 1000.0)
    scene.write_text(scene.read_text().replace("[scene]", '[scene]\nmodel = "torsion"'))
    cmd = [sys.executable, "-m", "dolfin_rod", "run", str(scene), "--out", str(tmp_path / "run"),
           "--quiet"]
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    csv_path = tmp_path / "run" / "timeseries.csv"
    deadline = time.time() + 60
    while time.time() < deadline:
        # the header line and more than 20 rows (the assertion below)
        if csv_path.exists() and csv_path.read_text().count("\n") > 21:
            break
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    s = read_csv(csv_path)
    assert len(s["time"]) > 20 and len(s["time"]) == summary["steps"] + 1
    assert np.allclose(np.diff(s["time"]), 0.01)


def test_scene_documentation_is_generated_from_the_schema():
    from dolfin_rod.cli import schema_markdown
    doc = (Path(__file__).resolve().parents[1] / "docs/scenes.md").read_text()
    assert schema_markdown().strip() in doc
