"""Contact with obstacles (issue 26, rod/contact.py, docs/contact.md): the barrier's
force and gap, Coulomb friction, the scene keys and their errors.

References: statics (a rod resting on a plane carries its weight; a propped cantilever
on a sphere or a cylinder takes the reaction 3 w L / 8 - 3 EI Delta / L^3 of beam theory
with the prop's settlement Delta); a rigid body on an incline (it slides with
acceleration g (sin a - mu cos a) for mu < tan a; for mu > tan a it creeps at the speed
y eps where the smoothed law's phi(y) = tan a / mu); the signed distances against their definitions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters
from dolfin_rod.rod.contact import (NP_OPS, ContactLaw, Obstacle, Pose, default_stiffness,
                                    signed_distance)
from dolfin_rod.scenes import SceneError, build, load_scene, parse_scene

G, R, DELTA = 9.81, 0.01, 1e-3
ROD = RodParameters(length=1.0, A=(1e-2, 1e-2, 1e-2), B=(10.0, 10.0, 10.0), density=1.0,
                    section_inertia=1e-5)
TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-12}
RHO_0 = "generalized_alpha:0.0"     # the contact scenes' integrator (docs/contact.md)


def _lying_rod(dt, gravity, friction=0.0, n_cells=8, drag=0.0, gap0=1.5 * DELTA, eps=1e-4):
    """A free rod along e_3 at gap gap0 above the plane x = -(r + gap0), under gravity."""
    params = RodParameters(**{**ROD.__dict__, "drag": drag})
    law = ContactLaw(R, DELTA, default_stiffness(params.density, params.A, 1.0, n_cells, dt),
                     slip_tolerance=eps)
    plane = Obstacle("plane", point=(-(R + gap0), 0.0, 0.0), normal=(1.0, 0.0, 0.0),
                     friction=friction)
    rod = RodModel(params, n_cells=n_cells, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad("force", tuple(gravity))],
                   obstacles=[plane], contact=law)
    rod.set_initial_state()
    return rod


def _history(rod, dt, n_steps, options=TIGHT):
    stepper = TimeStepper(rod.problem, RHO_0, options)
    rows = []
    for k in range(n_steps):
        stepper.run(k * dt, (k + 1) * dt, dt)
        rows.append(rod.diagnostics((k + 1) * dt))
    return rows


@pytest.mark.mpi
@pytest.mark.parametrize("dt", [1e-3, 1e-2, 1e-1])
def test_rod_resting_on_a_plane_carries_its_weight(dt):
    """Dropped from 1.5 delta with drag (c = 200: the heave on the barrier decays by
    1e-8 within 0.2 s): at rest the plane's total force is the weight
    rho_A g L (to the solver's tolerance: 1e-8 relative), the gap stays in (0, delta)
    at every step: no penetration, at any dt (the barrier's stiffness follows dt)."""
    rod = _lying_rod(dt, (-G, 0.0, 0.0), drag=200.0)    # decays at 100/s at least
    rows = _history(rod, dt, max(60, int(round(0.25 / dt))))
    gaps = [d["min_gap"] for d in rows]
    assert min(gaps) > 0.0
    assert 0.0 < rows[-1]["min_gap"] < DELTA
    assert rows[-1]["contact_force_x"] == pytest.approx(G * 1.0, rel=1e-8)
    assert abs(rows[-1]["contact_force_y"]) + abs(rows[-1]["contact_force_z"]) < 1e-10


@pytest.mark.mpi
def test_rod_slides_down_an_incline_with_kinetic_friction():
    """mu = 0.2 < tan 30 deg: the tip's acceleration along the slope (a quadratic fit of
    its position over the last 0.5 s) is g (sin a - mu cos a) to 1e-6 (the Coulomb force
    is exact beyond the slip tolerance; the fit's error is round-off); the friction's
    dissipation is >= 0 at every step and the power balance closes (K, Psi, contact
    energy, drag-free: P = D + d/dt E to 1e-5 of P)."""
    a, mu, dt = np.radians(30.0), 0.2, 1e-2
    rod = _lying_rod(dt, (-G * np.cos(a), 0.0, -G * np.sin(a)), friction=mu, gap0=0.9 * DELTA)
    rows = _history(rod, dt, 100, {**TIGHT, "snes_linesearch_type": "bt"})
    assert min(d["friction_dissipation"] for d in rows) >= 0.0
    t = np.array([d["time"] for d in rows])
    z = np.array([d["tip_position_z"] for d in rows])
    late = t > 0.5
    accel = 2 * np.polyfit(t[late], z[late], 2)[0]
    assert accel == pytest.approx(-G * (np.sin(a) - mu * np.cos(a)), rel=1e-6)
    assert rows[-1]["contact_force_x"] == pytest.approx(G * np.cos(a), rel=1e-8)
    energy = [d["kinetic_energy"] + d["free_energy"] + d["contact_energy"] for d in rows]
    for k in range(60, 99):   # the power balance on the steady slide, central differences
        rate = (energy[k + 1] - energy[k - 1]) / (2 * dt)
        P, D = rows[k]["load_power"], rows[k]["dissipation_rate"]
        assert rate + D - P == pytest.approx(0.0, abs=1e-5 * P)


@pytest.mark.mpi
def test_rod_sticks_on_an_incline_with_static_friction():
    """mu = 0.8 > tan 30 deg: after it settled (1 s), the rod moves less than the slip
    tolerance eps times 10 s over 10 s: it creeps at y eps with phi(y) = tan a / mu
    (y = 0.53, the smoothed law's root), to 1e-3; dissipation >= 0 at every step."""
    a, mu, dt, eps = np.radians(30.0), 0.8, 5e-2, 1e-4
    rod = _lying_rod(dt, (-G * np.cos(a), 0.0, -G * np.sin(a)), friction=mu,
                     gap0=0.9 * DELTA, eps=eps)
    rows = _history(rod, dt, 220, {**TIGHT, "snes_linesearch_type": "bt"})
    assert min(d["friction_dissipation"] for d in rows) >= 0.0
    z = {round(d["time"], 6): d["tip_position_z"] for d in rows}
    creep = abs(z[11.0] - z[1.0])
    assert creep < eps * 10.0
    # the creep speed y eps: mu lambda phi(y) = weight sin a, lambda = weight cos a
    y = brentq(lambda y: 1.5 * y - 0.5 * y**3 - np.tan(a) / mu, 0.0, 1.0)
    assert creep == pytest.approx(y * eps * 10.0, rel=1e-3)



def _incline_series(tmp_path, angle: float, mu: float, t_end: float, dt: float) -> dict:
    """The time series of SCENE's rod run as the CLI runs a scene (dolfin_rod.run), on
    its plane x = -(r + delta / 2) tilted by gravity at ``angle`` degrees from the
    plane's normal, friction ``mu``, every contact and solver setting at its default:
    gap r / 10, stiffness from dt, slip tolerance 1e-3 L / t_end, Newton to rtol 1e-8
    with bt and the l2 fallback (scenes/contact.contact_solver_options)."""
    from mpi4py import MPI

    from dolfin_rod import run
    a = np.radians(angle)
    text = (SCENE.replace("gravity = [-9.81, 0.0, 0.0]",
                          f"gravity = [{-G * np.cos(a)}, 0.0, {-G * np.sin(a)}]")
            .replace("friction = 0.3", f"friction = {mu}")
            .replace("t_end = 0.1", f"t_end = {t_end}").replace("dt = 0.01", f"dt = {dt}")
            + "[outputs]\nfields = false\nanimation = false\nplots = false\n")
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0)) / "run"
    result = run(parse_scene(text), out=folder, quiet=True)
    assert result.status == "completed", result.summary["message"]
    return {k: np.array(v, float) for k, v in result.series.items()}


@pytest.mark.mpi
@pytest.mark.parametrize("angle, mu", [(10.0, 0.05), (60.0, 1.2)])
def test_rod_slides_down_an_incline_at_the_scene_defaults(tmp_path, angle, mu):
    """A scene at its contact defaults (_incline_series), mu < tan a, from the nearly
    frictionless to a steep slope with mu = 1.2: the acceleration along the slope (a
    quadratic fit over t >= 0.5 s) is g (sin a - mu cos a) to 1e-6 (measured 6e-13 and
    3e-9: Newton's rtol 1e-8 at the defaults, not test_rod_slides_down_an_incline's
    1e-10), the plane carries the weight's normal part to 1e-8, friction's dissipation
    >= 0 at every step.  Measured on a grid of a = 10-60 degrees, mu = 0.05-1.2,
    8-33 cells, dt 5e-3-4e-2, r 2-50 mm, quaternions, 2 ranks: the same within 4e-7
    (docs/contact.md, "At the defaults")."""
    s = _incline_series(tmp_path, angle, mu, 1.0, 1e-2)
    a = np.radians(angle)
    late = s["time"] >= 0.5
    accel = -2 * np.polyfit(s["time"][late], s["tip_position_z"][late], 2)[0]
    assert accel == pytest.approx(G * (np.sin(a) - mu * np.cos(a)), rel=1e-6)
    assert s["contact_force_x"][-1] == pytest.approx(G * np.cos(a), rel=1e-8)
    assert s["friction_dissipation"].min() >= 0.0


@pytest.mark.mpi
def test_rod_sticks_on_an_incline_at_the_scene_defaults(tmp_path):
    """mu = 1.2 > tan 45 deg at the defaults (_incline_series), dt = 0.04 (4x the
    scene's), t_end = 11 s, so eps = 1e-3 L / t_end: from t = 1 s to 11 s the rod creeps
    less than eps * 10 s, at the smoothed law's speed y eps (phi(y) = tan a / mu,
    y = 0.645) to 1e-6 (measured 6e-12; the creep is steady once the rod has settled
    on the barrier, within 1 s); dissipation >= 0 at every step."""
    a, mu, t_end = np.radians(45.0), 1.2, 11.0
    s = _incline_series(tmp_path, 45.0, mu, t_end, 4e-2)
    eps = 1e-3 * 1.0 / t_end
    z = dict(zip(np.round(s["time"], 6), s["tip_position_z"]))
    creep = abs(z[11.0] - z[1.0])
    assert creep < eps * 10.0
    y = brentq(lambda y: 1.5 * y - 0.5 * y**3 - np.tan(a) / mu, 0.0, 1.0)
    assert creep == pytest.approx(y * eps * 10.0, rel=1e-6)
    assert s["friction_dissipation"].min() >= 0.0

PROPPED = (0.02, 1e-2)      # the propped cantilever's load per length w and EI


def _propped(obstacle, n: int = 16) -> dict:
    """A quasi-static cantilever (L = 1, EI = 1e-2, 16 cells) under w = 0.02 per length
    (ramped over t <= 1) whose tip rests on ``obstacle``: its diagnostics at t = 1."""
    return propped_rod(obstacle, n).diagnostics(1.0)


def propped_rod(obstacle, n: int = 16, curve: str = "smooth",
                rotations: str = "rotation_vector", scheme: str | None = None) -> RodModel:
    """The cantilever of ``_propped`` on ``obstacle`` (anywhere along it) at t = 1
    (contact.obstacle_curve ``curve``; its unknowns' ``rotations``, stepped by
    ``scheme``, default the rod's choice)."""
    w, EI = PROPPED
    params = RodParameters(length=1.0, A=(EI, EI, EI), B=(1e3, 1e3, 1e3))
    rod = RodModel(params, n_cells=n, model="hyperelastic", rotations=rotations,
                   distributed_loads=[DistributedLoad("force", (-w, 0.0, 0.0),
                                                      lambda t: min(t, 1.0))],
                   obstacles=[obstacle],
                   contact=ContactLaw(R, DELTA, default_stiffness(0.0, params.A, 1.0, n, 1.0),
                                      obstacle_curve=curve))
    rod.set_initial_state()
    stepper = TimeStepper(rod.problem, scheme, TIGHT)
    if scheme is None:                  # generalized-alpha's start
        stepper.initial_accelerations(0.0)
    stepper.run(0.0, 1.0, 0.1)
    return rod


@pytest.mark.mpi
@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_propped_cantilever_on_a_sphere_and_a_cylinder(shape):
    """A quasi-static cantilever under w = 0.02 per length whose tip rests on a sphere
    (cylinder across it): the contact force is beam theory's prop reaction
    3 w L / 8 - 3 EI Delta / L^3 with the measured settlement Delta of the tip (to 1 %:
    the FE's O(h^2) error at 16 cells and shear, 1e-3 here)."""
    w, EI = PROPPED
    R_obstacle, gap0 = 0.05, 0.5 * DELTA
    centre = (-(R + gap0 + R_obstacle), 0.0, 1.0)
    d = _propped(Obstacle(shape, centre=centre, axis=(0.0, 1.0, 0.0), radius=R_obstacle,
                          length=0.2))
    settlement = -d["tip_position_x"]
    reaction = 3 * w / 8 - 3 * EI * settlement
    assert 0.0 < d["min_gap"] < DELTA
    assert settlement < w / (8 * EI)       # held: the free cantilever's tip goes w/8EI
    assert d["contact_force_x"] == pytest.approx(reaction, rel=1e-2)


def test_signed_distances():
    """The three shapes' signed distances at points with known distances."""
    p = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 0.0], [0.0, 0.5, 0.0], [3.0, 0.0, 4.0]])
    plane = Obstacle("plane", point=(0.0, 0.0, 1.0), normal=(0.0, 0.0, 2.0))
    sphere = Obstacle("sphere", centre=(0.0, 0.0, 0.0), radius=1.0)
    cylinder = Obstacle("cylinder", centre=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0),
                        radius=1.0, length=2.0)
    assert signed_distance(Pose(plane), p, NP_OPS) == pytest.approx([1.0, -1.0, -1.0, 3.0])
    assert signed_distance(Pose(sphere), p, NP_OPS) == pytest.approx([1.0, 2.0, -0.5, 4.0])
    # cylinder |z| <= 1, rho <= 1: above the lid, beside the side, inside (to the side
    # 0.5 away), beyond the rim (distance to the edge circle: sqrt(2^2 + 3^2))
    assert signed_distance(Pose(cylinder), p, NP_OPS) == pytest.approx(
        [1.0, 2.0, -0.5, np.sqrt(13.0)])


# -- scenes ----------------------------------------------------------------------------------

SCENE = """
[material]
model = "hyperelastic"
stiffness = { A = [1e-2, 1e-2, 1e-2], B = [10.0, 10.0, 10.0] }
density = 1.0
section_inertia = 1e-5
[boundary]
start = "free"
end = "free"
[loads]
gravity = [-9.81, 0.0, 0.0]
[contact]
radius = 0.01
[[obstacles]]
shape = "plane"
point = [-0.0105, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
friction = 0.3
[time]
t_end = 0.1
dt = 0.01
"""


def _error(text: str) -> SceneError:
    with pytest.raises(SceneError) as err:
        scene = parse_scene(text)
        build(scene, "rod")
    return err.value


@pytest.mark.parametrize("change, key, also", [
    (("radius = 0.01", "radius = 0.01\ngap = 0.02"), "contact.gap", None),
    # one rod: between_rods paired nothing, silently (its own segments: contact.self)
    (("radius = 0.01", "radius = 0.01\nbetween_rods = true"), "contact.between_rods", None),
    (("friction = 0.3", "friction = -0.1"), "obstacles[0].friction", None),
    (("point = [-0.0105, 0.0, 0.0]", "point = [-0.005, 0.0, 0.0]"), "obstacles[0]", None),
    (("radius = 0.01\n", ""), "contact.radius", None),
    (("normal = [1.0, 0.0, 0.0]", "normal = [1.0, 0.0, 0.0]\naxis = [0.0, 1.0, 0.0]"),
     "obstacles[0].axis", None),
    (("normal = [1.0, 0.0, 0.0]", "normal = [0.0, 0.0, 0.0]"), "obstacles[0].normal", None),
    (("friction = 0.3", "contact = \"segments\""), "obstacles[0].contact", None),
    (("friction = 0.3", "contact = \"edges\""), "obstacles[0].contact", None),
    (('shape = "plane"', 'shape = "cylinder"'), "obstacles[0]",      # a thin bar across
     [("point = [-0.0105, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\nfriction = 0.3",  # a cell
       "centre = [0.0, 0.0, 0.05]\naxis = [0.0, 1.0, 0.0]\nradius = 0.003\nlength = 0.1"),
      ("[contact]", "[geometry]\nn_cells = 10\n[contact]")]),
    (('shape = "plane"', 'shape = "cylinder"'), "obstacles[0].friction",   # a thin bar
     [("point = [-0.0105, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]",        # 0.5 mm off,
       "centre = [-0.0135, 0.0, 0.05]\naxis = [0.0, 1.0, 0.0]\nradius = 0.003\n"
       "length = 0.1"),                          # on the segments (h = 0.1), quaternions
      ("[contact]", '[geometry]\nn_cells = 10\nrotations = "quaternion"\n[contact]')]),
    (("density = 1.0\nsection_inertia = 1e-5", ""), "obstacles[0].friction",
     [("gravity = [-9.81, 0.0, 0.0]", "distributed_force = { value = [-9.81, 0.0, 0.0] }"),
      ('start = "free"', 'start = "clamped"')]),
])
def test_bad_contact_input_names_the_key(change, key, also):
    """Each mistake: one SceneError naming the key, before any solve (an obstacle that
    cuts the rod at t = 0 included); the last: friction on a quasi-static rod."""
    text = SCENE
    for old, new in [change] + (also or []):
        assert old in text
        text = text.replace(old, new, 1)
    assert _error(text).key == key


@pytest.mark.parametrize("point, says", [
    ("-0.01", "touches obstacles[0] at t = 0 (gap 0 between the surfaces"),
    ("-0.005", "is 0.005 closer to obstacles[0] than the rod's radius at t = 0 (it cuts"),
])
def test_initial_overlap_says_where_the_rod_may_start(point, says):
    """A rod laid on the plane at its radius (gap exactly 0, the barrier infinite: how a
    user puts a rope on a floor) is told that it touches, not that it is "-0 closer";
    a rod cutting 5 mm into it how far; both where it may start: a gap in (0, delta],
    delta = r / 10 = 0.001 by default."""
    err = _error(SCENE.replace("point = [-0.0105, 0.0, 0.0]", f"point = [{point}, 0.0, 0.0]"))
    assert err.key == "obstacles[0]"
    assert says in str(err)
    assert "start it off the surface by a gap in (0, 0.001] (contact.gap" in str(err)
    assert "-0 " not in str(err) and "triangles" not in str(err)      # a plane


ROD_B = """
[[rods]]
name = "a"
[[rods]]
name = "b"
position = [0.1, 0.0, 0.0]
orientation = [0.0, -1.5707963267948966, 0.0]
"""
KINKED = ('[geometry]\nn_cells = 10\nreference_shape = { type = "polyline", points = '
          '[[0.0, 0.0, 0.0], [0.0, 0.0, 0.5], [-0.3, 0.0, 0.9]] }\n[contact]')


@pytest.mark.parametrize("change, says", [
    ((), "the rod's centre line at s = 0 is 0.005 closer to obstacles[0] than the rod's "
         "radius at t = 0 (it cuts into the obstacle)"),
    ((("[contact]", ROD_B + "[contact]"),), "the centre line of rod 'b' at s = 1 is 0.905 "
                                            "closer to obstacles[0]"),
    ((("[contact]", KINKED), ("point = [-0.005, 0.0, 0.0]", "point = [-0.2, 0.0, 0.0]")),
     "the rod's centre line at s = 1 is 0.11 closer to obstacles[0]"),
])
def test_check_refuses_a_rod_that_starts_inside_an_obstacle(tmp_path, change, says):
    """As a user runs it: ``dolfin-rod check`` exits 2 naming obstacles[0], with where
    along the rod (its own arc length), how deep and where it may start, before any model
    (was: OK, and ``run`` refused it after building the model).  The plane x = -0.005 of
    SCENE: the rod along e_3 (r = 0.01) is 0.005 in at every node, the first at s = 0;
    rod b of a system from x = 0.1 along -e_1: node s at x = 0.1 - s, gap 0.095 - s,
    the deepest at s = 1 (rod a as SCENE's); a rod bent at s = 0.5 (split there into two pieces) towards
    -e_1, its nodes past the corner at x = -0.6 (s - 0.5), the plane x = -0.2: the
    deepest at s = 1, x = -0.3, gap -0.3 + 0.2 - 0.01."""
    from test_cli import cli
    text = SCENE.replace("point = [-0.0105, 0.0, 0.0]", "point = [-0.005, 0.0, 0.0]")
    for old, new in change:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "scene.toml"
    path.write_text(text)
    proc = cli("check", path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.count("\n") == 1 and "[obstacles[0]]" in proc.stderr
    assert says in proc.stderr
    assert "start it off the surface by a gap in (0, 0.001] (contact.gap" in proc.stderr
    path.write_text(text.replace("point = [-0.005, 0.0, 0.0]", "point = [-0.0105, 0.0, 0.0]")
                    .replace("point = [-0.2, 0.0, 0.0]", "point = [-0.4, 0.0, 0.0]")
                    .replace("position = [0.1,", "position = [1.1,"))
    assert cli("check", path).returncode == 0       # the same rods 0.5 mm off the plane


def test_check_refuses_a_thin_bar_cutting_a_cell(tmp_path):
    """rope_over_thin_bar.toml with the bar 2 mm higher: its axis 8 mm below the rope,
    radius 4 mm, the rope's r = 5 mm: the cell across it (its midpoint s = 0.5 over the
    axis; 31 cells, the nodes 16 mm on either side, clear of the bar) cuts 1 mm into it.
    ``dolfin-rod check`` exits 2 naming obstacles[0] with the model's message (was: OK,
    and ``run`` refused it after building the model); the bar where it was passes."""
    from test_cli import cli
    text = (Path(__file__).parents[1] / "scenes" / "rope_over_thin_bar.toml").read_text()
    path = tmp_path / "scene.toml"
    path.write_text(text.replace("centre = [0.0, 0.0, -0.01]", "centre = [0.0, 0.0, -0.008]"))
    proc = cli("check", path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert ("[obstacles[0]]: the rod's segment at s = 0.5 is 0.001 closer to obstacles[0] "
            "than the rod's radius at t = 0") in proc.stderr


def test_check_and_the_model_say_the_same_of_an_overlap():
    """The rod of SCENE 5 mm inside the plane: the model's own check at t = 0 (the
    Python API, RodModel.set_initial_state) raises the message ``dolfin-rod check``
    gives."""
    plane = Obstacle("plane", point=(-0.005, 0.0, 0.0), normal=(1.0, 0.0, 0.0))
    rod = RodModel(ROD, n_cells=8, model="hyperelastic", start="free", end="free",
                   obstacles=[plane], contact=ContactLaw(R, DELTA, 1.0))
    with pytest.raises(ValueError) as model:
        rod.set_initial_state()
    scene = _error(SCENE.replace("point = [-0.0105, 0.0, 0.0]", "point = [-0.005, 0.0, 0.0]")
                   .replace("friction = 0.3", "friction = 0.0"))
    assert str(scene).endswith(str(model.value))


def test_a_rod_behind_a_mesh_hears_of_the_triangles_orientation():
    """The plane of SCENE as a mesh square (x = -0.0105) whose triangles are clockwise
    seen from the rod (their normal -x, the rod behind them: how an open bowl comes out
    when given from inside): the rod's nodes are 0.0105 behind the surface, gap -0.0105
    - r = -0.0205; the error says so and that the triangles may face the wrong way."""
    mesh = ('vertices = [[-0.0105, -1.0, -1.0], [-0.0105, 1.0, -1.0], [-0.0105, 1.0, 2.0], '
            '[-0.0105, -1.0, 2.0]]\ntriangles = [[0, 2, 1], [0, 3, 2]]')
    text = SCENE.replace('shape = "plane"', 'shape = "mesh"').replace(
        "point = [-0.0105, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]", mesh)
    err = _error(text)
    assert err.key == "obstacles[0]"
    assert "is 0.0205 closer to obstacles[0]" in str(err)
    assert "the triangles of obstacles[0] face the other way: give them counter-clockwise " \
           "seen from the rod's side" in str(err)


def test_contact_scene_runs_and_rests():
    """The scene above (friction 0.3): the example scene's keys map to the model, the
    plane carries the weight after 0.1 s (to 1 %: the drop from 0.5 delta still rings)."""
    scene = parse_scene(SCENE.replace("t_end = 0.1", "t_end = 0.5"))
    sim = build(scene, "rod")
    sim.start()
    sim.begin(0.0)
    for k in range(50):
        sim.advance(0.01 * k, 0.01 * (k + 1))
    d = sim.diagnostics(0.5)
    assert d["contact_force_x"] == pytest.approx(9.81, rel=1e-2)
    assert 0.0 < d["min_gap"] < 0.001


def test_example_scenes_validate():
    for name in ("rod_on_incline", "rope_on_floor"):
        assert load_scene(f"scenes/{name}.toml")["obstacles"]


@pytest.mark.parametrize("shape", ["plane", "sphere", "cylinder"])
def test_contact_jacobian_is_the_residuals_derivative(shape):
    """Taylor test of the assembled contact terms at a state inside the barrier:
    |R(x + h dx) - R(x) - h J dx| = O(h^2) (the remainder falls 4-fold per halving of h)
    for the residual R = dE/dx of the contact energy and its Jacobian J, as Newton
    needs for quadratic convergence; the energy's remainder likewise with R."""
    import dolfinx.fem as fem
    import dolfinx.fem.petsc as fem_petsc
    import ufl
    rod = _lying_rod(1e-2, (-G, 0.0, 0.0), n_cells=4, gap0=0.5 * DELTA)
    if shape != "plane":        # a sphere / cylinder under the rod's middle, its law on
        # the nodes (these forms): thinner than the cells (0.25), "auto" takes the segments
        ob = Obstacle(shape, centre=(-(R + 0.5 * DELTA + 0.05), 0.0, 0.5),
                      axis=(0.0, 1.0, 0.0), radius=0.05, length=0.1, contact="nodes")
        rod = RodModel(ROD, n_cells=4, model="hyperelastic", start="free", end="free",
                       obstacles=[ob], contact=ContactLaw(R, DELTA, 1e3))
        rod.set_initial_state()
    x = rod.f["displacement"]
    rng = np.random.default_rng(1)
    x.x.array[:] += 1e-4 * DELTA * rng.standard_normal(x.x.array.size)
    dx = fem.Function(x.function_space)
    dx.x.array[:] = 0.1 * DELTA * rng.standard_normal(x.x.array.size)
    E_form = rod.contact.energy()
    R_form = ufl.derivative(E_form, x, ufl.TestFunction(x.function_space))
    J_form = ufl.derivative(R_form, x, ufl.TrialFunction(x.function_space))
    E, Rf, J = fem.form(E_form), fem.form(R_form), fem.form(J_form)
    x0 = x.x.array.copy()
    e0 = fem.assemble_scalar(E)
    r0 = fem_petsc.assemble_vector(Rf).array.copy()
    A = fem_petsc.assemble_matrix(J)
    A.assemble()
    Jdx = A.createVecLeft()
    A.mult(dx.x.petsc_vec, Jdx)
    remainders = []
    for h in (1e-1, 5e-2, 2.5e-2):
        x.x.array[:] = x0 + h * dx.x.array
        r = fem_petsc.assemble_vector(Rf).array
        e = fem.assemble_scalar(E)
        remainders.append((np.linalg.norm(r - r0 - h * Jdx.array),
                           abs(e - e0 - h * r0 @ dx.x.array)))
    x.x.array[:] = x0
    for coarse, fine in zip(remainders, remainders[1:]):
        for c, f in zip(coarse, fine):
            assert c / f == pytest.approx(4.0, rel=0.1)


@pytest.mark.mpi
def test_a_barrier_that_yields_fails_the_run_naming_the_obstacle(tmp_path):
    """contact.stiffness 1e-3 (1e-7 of the default) cannot hold the rod: the steps are
    cut, then the run fails ('failed': the CLI's exit 3) naming the obstacle, the place
    and the key to raise; the rows computed before are kept."""
    from mpi4py import MPI

    from dolfin_rod import run_scene
    # no pictures or fields: the test reads the summary and the rows
    scene = parse_scene(SCENE.replace("radius = 0.01", "radius = 0.01\nstiffness = 1e-3")
                        .replace("t_end = 0.1", "t_end = 0.5")
                        + "[outputs]\nfields = false\nanimation = false\nplots = false\n")
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0)) / "run"
    summary = run_scene(scene, folder, quiet=True)
    assert summary["status"] == "failed"
    assert "inside obstacles[0]" in summary["message"]
    assert "contact.stiffness" in summary["message"]
    if MPI.COMM_WORLD.rank == 0:
        rows = (folder / "timeseries.csv").read_text().splitlines()
        assert len(rows) > 2


def _capstan(mu: float, ratio: float, n_cells: int = 64, dt: float = 2e-3):
    """A rope (r = 5 mm, 0.1 kg/m, EI = 1e-5) draped over a cylinder (radius 5 cm, axis
    e_2, friction mu) with overhangs h1 = 0.2 m and h2 = ratio h2*, under gravity -x
    ramped up over 0.5 s; the tip's (end of the h2 side) x over t."""
    from dolfin_rod.rod.start import Polyline, StartingState
    Rc, r, delta = 0.05, 0.005, 5e-4
    rho = Rc + r + 0.5 * delta                        # the centre line's radius on it
    e = np.exp(mu * np.pi)
    h1 = 0.2
    h2 = ratio * (e * h1 + rho * (2 * mu / (1 + mu**2)) * (e + 1))
    phi = np.linspace(-np.pi / 2, np.pi / 2, 200)
    points = np.concatenate([[[-h1, 0, -rho]], np.stack([rho * np.cos(phi), 0 * phi,
                                                          rho * np.sin(phi)], 1),
                             [[-h2, 0, rho]]])
    L = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    params = RodParameters(length=L, A=(1e-5,) * 3, B=(50.0, 50.0, 100.0), density=0.1,
                           section_inertia=1e-7)
    law = ContactLaw(r, delta, default_stiffness(params.density, params.A, L, n_cells, dt),
                     slip_tolerance=1e-3)
    cylinder = Obstacle("cylinder", centre=(0, 0, 0), axis=(0, 1, 0), radius=Rc, length=0.2,
                        friction=mu)
    rod = RodModel(params, n_cells=n_cells, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad("force", (-G * params.density, 0, 0),
                                                      lambda t: min(t / 0.5, 1.0))],
                   obstacles=[cylinder], contact=law)
    rod.set_initial_state(start=StartingState(
        shape=Polyline(tuple(map(tuple, points - points[0])), normal=(0.0, 0.0, 1.0)),
        position=tuple(points[0])))
    return rod, _history(rod, dt, int(round(1.5 / dt)),
                         {"snes_rtol": 1e-8, "snes_atol": 1e-9, "snes_linesearch_type": "bt"})


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("mu", [0.1, 0.3, 0.6])
def test_capstan_holds_below_the_overhang_and_slides_above(mu):
    """The capstan: the longest overhang that holds is h2* = e^{mu pi} h1 + R (2 mu /
    (1 + mu^2)) (e^{mu pi} + 1) (R the centre line's radius on the cylinder).  At
    0.95 h2* the rope holds: over the last 0.75 s it creeps at most at 2.5 eps (near the
    limit friction is used almost fully along the contact, where the smoothed law creeps
    at up to eps; measured 2.1e-3, 1.2e-3, 5.6e-6 m/s for mu = 0.1, 0.3, 0.6); at 1.05 h2*
    it slides at > 0.5 m/s (measured 1.4-2.8 m/s), 300 times faster.  Under `mpirun -n 2`
    too (2 ranks at load 10-12 on 2 cores: mu = 0.6 1297 s, mu = 0.1 and 0.3 687 s)."""
    speeds = []
    for ratio in (0.95, 1.05):
        _, rows = _capstan(mu, ratio)
        late = [d for d in rows if d["time"] >= 0.75 - 1e-9]
        speeds.append(abs(late[-1]["tip_position_x"] - late[0]["tip_position_x"])
                      / (late[-1]["time"] - late[0]["time"]))
        assert min(d["min_gap"] for d in rows) > 0.0
    assert speeds[0] < 2.5e-3
    assert speeds[1] > 0.5


def test_polyline_start_turning_by_pi_has_continuous_rotations():
    """The capstan's start (a polyline turning by pi): neighbouring nodal quaternions in
    one hemisphere (q_k . q_k+1 > 0; a sign flip made the strains infinite)."""
    from dolfin_rod.rod.start import Polyline, continuous
    phi = np.linspace(0.0, np.pi, 50)
    points = np.stack([np.sin(phi), 0 * phi, 1 - np.cos(phi)], 1)
    L = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    _, q = Polyline(tuple(map(tuple, points)), normal=(1.0, 0.0, 0.0)).frames(
        np.linspace(0, L, 41), L, 40)
    assert np.all(np.einsum("ij,ij->i", q[1:], q[:-1]) > 0.9)
    flipped = q * np.where(np.arange(len(q)) % 3 == 0, -1.0, 1.0)[:, None]
    assert np.allclose(continuous(flipped), -q)      # the first node keeps its sign
