"""What the terminal says (issue 29 item 3): `check` names the rotation unknowns and why,
in plain words, for every reason rod/rotation_choice.py knows."""

from __future__ import annotations

import io
import time

import pytest

from dolfin_rod.cli import main
from dolfin_rod.rod.rotation_choice import choose_rotations, rotations_reason
from quick_scenes import ROOT

SCENES = ROOT / "scenes"


@pytest.mark.parametrize("args, start, why", [
    (("auto", None), "rotation vectors", "nothing here needs quaternions"),
    (("auto", "the uniform variant (use the local one)"), "quaternions",
     "do not fit here: the uniform variant"),
    (("auto", None, True, True), "quaternions", "a prescribed end rotation jumps"),
    (("auto", None, False), "quaternions", "the integrator does not step rotation vectors"),
    (("quaternion", None), "quaternions", "geometry.rotations = 'quaternion' in the scene"),
])
def test_rotation_reason_follows_the_choice(args, start, why):
    """The sentence names the unknowns choose_rotations picks and the rule that picked
    them."""
    text = rotations_reason(*args)
    chosen = choose_rotations(*args)
    assert text.startswith(start) and why in text
    assert (chosen == "rotation_vector") == text.startswith("rotation vectors")


@pytest.mark.parametrize("scene, line", [
    ("gravity_cantilever", "rotations: rotation vectors (a rotation increment of 3 unknowns"),
    ("dna_twist_relaxation", "a prescribed end rotation jumps"),   # a step of end_rotation
])
def test_check_says_why(scene, line, capsys):
    assert main(["check", str(SCENES / f"{scene}.toml")]) == 0
    assert line in capsys.readouterr().out


def test_closing_summary_gives_each_rods_tip_and_reaction():
    """A rod system (the bundled frame: rods "column" and "beam") whose column tip moved
    by (0, 0, -0.01) and beam tip by (0.5, 0, -1.25), the column clamped with a 3 N
    reaction: one line per rod for the tip and for the reaction, in the scene's units."""
    from dolfin_rod.output.closing import final_values
    from dolfin_rod.scenes import load_scene
    scene = load_scene(SCENES / "frame.toml")
    keys = ["free_energy", "kinetic_energy", "total_dissipation", "dissipation_rate",
            "load_power", "power_residual"]
    for rod in ("column.", "beam."):
        keys += [f"{rod}tip_position_{c}" for c in "xyz"]
    keys += [f"column.reaction_{kind}_start_{c}" for kind in ("force", "couple") for c in "xyz"]
    first = {"time": 0.0, **dict.fromkeys(keys, 0.0)}
    last = {**first, "time": 1.0, "column.tip_position_z": -0.01,
            "beam.tip_position_x": 0.5, "beam.tip_position_z": -1.25,
            "column.reaction_force_start_z": 3.0}
    lines = final_values([first, last], scene)
    assert "column: tip displacement [0, 0, -0.01] m" in lines
    assert "beam: tip displacement [0.5, 0, -1.25] m" in lines
    assert "column: reaction at s = 0: force [0, 0, 3] N, couple [0, 0, 0] N m" in lines


def test_a_long_compile_is_announced_once(tmp_path):
    """Two forms never compiled before (a new constant in each: a new FFCx signature, so
    FFCx generates and compiles C for them), the notice due after 0 s: the stream gets
    the line once, with the estimate recorded here; without a stream nothing is said."""
    import json
    import uuid

    import ufl
    from dolfinx import fem, mesh
    from mpi4py import MPI

    from dolfin_rod.fem import compile_notice
    domain = mesh.create_unit_interval(MPI.COMM_SELF, 2)
    x = ufl.SpatialCoordinate(domain)[0]
    fresh = lambda: (x + uuid.uuid4().int % 10**9 / 7.0) * ufl.dx    # noqa: E731
    (tmp_path / "seconds.json").write_text(json.dumps({"cold_compile_seconds": 12.4}))
    with (tmp_path / "terminal").open("w") as stream:
        with compile_notice.listening(stream, after=0.0):
            for _ in range(2):
                with compile_notice.watching(tmp_path):
                    fem.form(fresh())
                    time.sleep(0.3)       # the child's sh starts and prints in this time
        with compile_notice.watching(tmp_path):     # no stream: silent
            fem.form(fresh())
    assert (tmp_path / "terminal").read_text() == \
        "compiling kernels (first run only, about 12 s)\n"
    assert compile_notice.estimate(tmp_path / "nothing") == "up to a minute"
    # a stream without a file descriptor (pytest's capture, a notebook's output): the
    # run goes on silently (io.UnsupportedOperation from Popen stopped every run before)
    captured = io.StringIO()
    with compile_notice.listening(captured, after=0.0):
        with compile_notice.watching(tmp_path):
            fem.form(fresh())
    assert captured.getvalue() == ""


def test_the_packages_warnings_reach_stderr_on_both_releases():
    """DOLFINx 0.9's FFCx routes every Python warning to a logger without a handler on
    import: the package's warnings (a cut step, a first-order restart) never reached a
    user (fem/compat.py undoes it).  A user's process: the public API, then a warning."""
    import subprocess
    import sys
    code = ("import warnings, dolfin_rod; dolfin_rod.RodModel; "
            "warnings.warn('a step was cut', RuntimeWarning)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert done.returncode == 0 and "RuntimeWarning: a step was cut" in done.stderr, done


def test_a_large_power_residual_is_explained():
    """The closing line of the power balance: a run whose residual reaches 0.6 of the
    power scale (rows made by hand: E = K + Psi rises by 1 J over a step of 1 s with
    D = P = 0, then by 0.6 J with P = 1 W: residuals 1 and 0.4 of the scale 1) is told
    what D leaves out; one of 1e-3 is only shown."""
    from dolfin_rod.output.closing import power_line
    from dolfin_rod.output.plots import relative_power_residual
    base = {"free_energy": 0.0, "kinetic_energy": 0.0, "dissipation_rate": 0.0,
            "load_power": 0.0, "power_residual": 0.0}
    rows = [{**base, "time": 0.0}, {**base, "time": 1.0, "free_energy": 1.0, "power_residual": 1.0},
            {**base, "time": 2.0, "free_energy": 1.6, "load_power": 1.0, "power_residual": -0.4}]
    assert list(relative_power_residual(rows)) == [1.0, 0.4]
    assert "numerical damping" in power_line(0.4)
    assert power_line(1e-3) == "power balance: largest relative residual after the first step 0.001"
