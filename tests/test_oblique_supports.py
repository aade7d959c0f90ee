"""A clamped end that slides along, and turns about, an axis off the coordinate axes
(issue 25 item 3: one-node links, fem/multipoint.NodeLine), against closed forms
re-derived in each test's docstring."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from quick_scenes import ROOT, assert_serial_run_equal, quick_scene
from scipy.optimize import brentq

from dolfin_rod import TimeStepper, loads, run_scene
from dolfin_rod.fem.fe_model import NodeValues
from dolfin_rod.rod import EndLoad, Rod, RodModel, RodParameters, RodSystem
from dolfin_rod.theory.quaternions import CONJ, np_qmul

comm = MPI.COMM_WORLD
TIGHT = {"snes_rtol": 1e-11, "snes_atol": 1e-12}
AXIS = np.ones(3) / np.sqrt(3.0)          # the rod's tangent and the clamp's axis
E3 = np.array([0.0, 0.0, 1.0])
L, EA, GJ, W, C, N = 1.5, 30.0, 2.0, 0.9, 0.3, 4


def along_the_axis() -> np.ndarray:
    """The rotation vector that turns e_3 into AXIS (the rod's orientation)."""
    normal = np.cross(E3, AXIS)
    return normal / np.linalg.norm(normal) * np.arccos(AXIS @ E3)


def inclined_rod(dynamic: bool = False) -> RodSystem:
    """A straight rod along AXIS = (1, 1, 1)/sqrt 3 from the origin, clamped at its top
    s = L; its bottom s = 0 in a clamp that slides along AXIS and turns about it, loaded
    there by a weight W (-W e_z) and a couple C AXIS, both ramped over [0, 1]."""
    ramp = loads.ramp(1.0, 1.0)
    inertia = dict(density=0.5, section_inertia=1e-3, drag=5.0,
                   rotational_drag=(0.05, 0.05, 0.05)) if dynamic else {}
    rod = Rod(RodParameters(length=L, A=(1.0, 1.0, GJ), B=(20.0, 20.0, EA), **inertia),
              n_cells=N, start="clamped", end="clamped", orientation=tuple(along_the_axis()),
              end_slide={"start": tuple(AXIS)}, end_turn={"start": tuple(AXIS)},
              end_loads=[EndLoad("force", (0.0, 0.0, -W), ramp, end="start"),
                         EndLoad("couple", tuple(C * AXIS), ramp, end="start")])
    return RodSystem([rod], model="hyperelastic")


def bottom(model) -> tuple[np.ndarray, np.ndarray]:
    """(displacement, rotation quaternion) of the node s = 0 (stored rotation: theta = 0
    after a step), on every rank."""
    x = model.unknowns.f["displacement"]
    q_n = model.unknowns.chart.q_n
    return (NodeValues(x.function_space, [0.0])(x.x.array)[0],
            NodeValues(q_n.function_space, [0.0])(q_n.x.array)[0])


def run(model, t_end, dt, scheme=None, observe=None):
    model.set_initial_state()
    rows = []

    def observer(t, _):
        rows.append(model.diagnostics(t))
        if observe:
            observe(t)

    TimeStepper(model.problem, scheme, solver_options=TIGHT).run(0.0, t_end, dt, observer)
    return rows


def twist_angle() -> float:
    """The discrete rod's twist under the end couple C (closed_forms.p1_twist, as in
    test_supports): the end turns by 4 N x with C = GJ 4 tan(x)/(h cos^2 x)."""
    h = L / N
    return 4 * N * brentq(lambda x: GJ * 4 * np.tan(x) / h / np.cos(x) ** 2 - C, 0.0, 0.5)


@pytest.mark.mpi
def test_weight_on_an_inclined_sliding_turning_clamp():
    """Quasi-static.  The clamp takes every force across AXIS and every couple across it,
    so the rod carries only the weight's part along it, the tension N = W (e_z . AXIS) =
    W/sqrt 3, and the couple C about it: it stays straight along AXIS, stretched by
    N L/EA (the P1 bar is nodally exact) and twisted as at a free end (p1_twist).  So
    the bottom clamp sits at -(N L/EA) AXIS (it moves along AXIS only: its part across
    is round-off), turned about AXIS by the twist; the top clamp carries N AXIS and the
    couple -C AXIS; the bottom clamp carries the weight's part across AXIS, W e_z - N
    AXIS, and no couple.  Tolerance: Newton's (rtol 1e-11) on quantities ~1."""
    model = inclined_rod()
    assert model.rotations == "rotation_vector"
    d = run(model, 1.0, 0.5, scheme="backward_euler")[-1]
    tension = W * AXIS[2]
    x, q = bottom(model)
    assert np.allclose(x, -tension * L / EA * AXIS, rtol=0, atol=1e-12)
    assert np.linalg.norm(x - (x @ AXIS) * AXIS) < 1e-14       # only along the axis
    turn = np_qmul(q, model.stress_free([0.0])[1][0] * CONJ)     # spatial: q = turn q_sf
    assert np.linalg.norm(np.cross(turn[1:], AXIS)) < 1e-14        # about AXIS only
    assert 2 * np.arctan2(abs(turn[1:] @ AXIS), abs(turn[0])) == pytest.approx(
        twist_angle(), rel=1e-9)

    def vector(key):
        return np.array([d[f"rod.{key}_{c}"] for c in "xyz"])

    assert np.allclose(vector("reaction_force_end"), tension * AXIS, rtol=0, atol=1e-10)
    assert np.allclose(vector("reaction_force_start"), W * E3 - tension * AXIS, rtol=0,
                       atol=1e-10)
    assert np.allclose(vector("reaction_couple_end"), -C * AXIS, rtol=0, atol=1e-10)
    assert np.linalg.norm(vector("reaction_couple_start")) < 1e-10
    assert np.allclose(vector("tip_position"), L * AXIS, rtol=0, atol=1e-14)


@pytest.mark.mpi
def test_dynamic_rod_on_an_inclined_sliding_clamp_settles_and_stays_on_the_axis():
    """Dynamic, the same rod with mass, rotary inertia and damping (drag c = 5, rotational
    drag 0.05 per length), the loads ramped over 1 s: at every step the bottom clamp is
    on its axis (the part of its displacement across AXIS is round-off: the link holds
    it exactly, also through the start's accelerations), and by t = 4 the damped
    motion (axial decay exp(-c t/(2 rho A)) = exp(-5 t)) has settled to the static
    stretch -(N L/EA) AXIS (measured 4.2e-6 relative; the top clamp's force 6.3e-7)."""
    model = inclined_rod(dynamic=True)
    across = []
    rows = run(model, 4.0, 0.05, observe=lambda t: across.append(
        np.linalg.norm(bottom(model)[0] - (bottom(model)[0] @ AXIS) * AXIS)))
    assert max(across) < 1e-14
    stretch = W * AXIS[2] * L / EA
    assert bottom(model)[0] @ AXIS == pytest.approx(-stretch, rel=3e-5)      # 4.2e-6
    assert rows[-1]["rod.reaction_force_end_x"] == pytest.approx(W * AXIS[2] ** 2,
                                                                 rel=1e-5)  # 6.3e-7


@pytest.mark.parametrize("axis, match", [
    ((0.0, 0.0, 0.0), "must be a unit vector"),
    ((0.6, 0.6, 0.6), "must be a unit vector"),
])
def test_a_slide_axis_that_is_not_unit_is_refused_naming_it(axis, match):
    with pytest.raises(ValueError, match=r"end_slide\['end'\] " + match):
        RodModel(RodParameters(), n_cells=2, start="clamped", end="clamped",
                 end_slide={"end": axis})


def test_inclined_supports_need_rotation_vectors_and_no_motion_across():
    with pytest.raises(ValueError, match=r"end_slide\['end'\]: an axis off the coordinate "
                                         "axes needs rotation-vector unknowns"):
        RodModel(RodParameters(), n_cells=2, start="clamped", end="clamped",
                 rotations="quaternion", end_slide={"end": (0.6, 0.0, 0.8)})
    with pytest.raises(ValueError, match=r"end_displacement\['end'\]: the end slides"):
        RodModel(RodParameters(), n_cells=2, start="clamped", end="clamped",
                 end_slide={"end": (0.6, 0.0, 0.8)},
                 end_displacement={"end": lambda t: (0.0, t, 0.0)})


INCLINED = ROOT / "scenes/inclined_clamp.toml"
QUIET = dict(outputs__animation=False, outputs__plots=False, outputs__fields=False)


@pytest.mark.mpi
def test_inclined_clamp_scene_serially_and_on_two_ranks(tmp_path):
    """scenes/inclined_clamp.toml (its 4 steps): the top clamp carries the weight's part
    along the rail, N a with N = W/sqrt 3 (each component W/3), the carriage the rest,
    W e_z - N a, and no couple (test_weight_on_an_inclined_sliding_turning_clamp's
    closed form; Newton's tolerance on ~0.3 N); 2 ranks give the serial time series to
    round-off."""
    folder = Path(comm.bcast(str(tmp_path), root=0))
    final = run_scene(quick_scene(INCLINED, 4, **QUIET), folder / "run", quiet=True)["final"]
    weight = 0.5
    for c in "xyz":
        assert final[f"rod.reaction_force_end_{c}"] == pytest.approx(weight / 3, rel=1e-8)
        assert final[f"rod.reaction_force_start_{c}"] == pytest.approx(
            (weight if c == "z" else 0.0) - weight / 3, rel=1e-8)
        assert abs(final[f"rod.reaction_couple_start_{c}"]) < 1e-10
    if comm.size > 1 and comm.rank == 0:
        assert_serial_run_equal(INCLINED, folder, 4, **QUIET)


@pytest.mark.parametrize("axis", [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
def test_inclined_clamp_scene_with_a_bad_axis_exits_2_naming_the_key(tmp_path, axis):
    text = INCLINED.read_text().replace(
        "start_slide = [0.5773502691896258, 0.5773502691896258, 0.5773502691896258]",
        f"start_slide = {axis}")
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(scene)],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "rods[0].boundary.start_slide" in out.stderr and "unit vector" in out.stderr
