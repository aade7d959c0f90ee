"""PyElastica's continuum snake (docs/scenes.md, "Coming from PyElastica"): directional
friction (an obstacle's forward, backward and lateral coefficients, rod/contact.py) and
a muscle's travelling wave of active bending moment (loads.muscle,
rod/external_forces.TravellingWave).

References: a rigid rod sliding on an incline accelerates at g (sin a - mu cos a) with
the coefficient of the direction it slides in; equal coefficients are the isotropic law
(tests/test_contact.py's closed forms); a rod at rest under an active moment M alone has
m = M, its curvature u = M / B (the quadratic energy); the B-spline of the amplitude is
PyElastica's own (elastica.external_forces._bspline); the snake's average speed against
PyElastica's run of its example (benchmarks/snake_peer.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import ufl

from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters, TravellingWave
from dolfin_rod.rod.contact import ContactLaw, Obstacle, default_stiffness
from dolfin_rod.scenes import SceneError, parse_scene

G, R, DELTA, A = 9.81, 0.01, 1e-3, np.radians(30.0)
TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-12, "snes_linesearch_type": "bt"}
FORWARD, BACKWARD, LATERAL = 0.1, 0.3, 0.04


def slide(slope: tuple, **friction) -> list[dict]:
    """A free rod along e_3 (L = 1, 8 cells, rho A = 1) lying on the plane x = -(r + 0.9
    delta), the slope made by tilting gravity by 30 degrees from the plane's normal
    towards ``slope`` (a unit vector in the plane); ``friction``: the Obstacle's keys.
    Its diagnostics over 1 s at dt = 0.01."""
    params = RodParameters(length=1.0, A=(1e-2, 1e-2, 1e-2), B=(10.0, 10.0, 10.0),
                           density=1.0, section_inertia=1e-5)
    dt = 1e-2
    gravity = G * (-np.cos(A) * np.array([1.0, 0.0, 0.0]) + np.sin(A) * np.asarray(slope))
    rod = RodModel(params, n_cells=8, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad("force", tuple(gravity))],
                   obstacles=[Obstacle("plane", point=(-(R + 0.9 * DELTA), 0.0, 0.0),
                                       normal=(1.0, 0.0, 0.0), **friction)],
                   contact=ContactLaw(R, DELTA, default_stiffness(1.0, params.A, 1.0, 8, dt),
                                      slip_tolerance=1e-4))
    rod.set_initial_state()
    stepper = TimeStepper(rod.problem, "generalized_alpha:0.0", TIGHT)
    rows = []
    for k in range(100):
        stepper.run(k * dt, (k + 1) * dt, dt)
        rows.append(rod.diagnostics((k + 1) * dt))
    return rows


def acceleration(rows: list[dict], axis: str) -> float:
    """The tip's acceleration along ``axis`` on the steady slide (a quadratic fit over
    t > 0.5 s)."""
    t = np.array([d["time"] for d in rows])
    x = np.array([d[f"tip_position_{axis}"] for d in rows])
    return 2 * np.polyfit(t[t > 0.5], x[t > 0.5], 2)[0]


@pytest.mark.mpi
def test_equal_directional_coefficients_are_the_isotropic_law():
    """forward = backward = lateral = 0.2 on the incline along the rod's axis: the
    isotropic law's run to round-off (1e-9 of the distance slid: the forms differ, mu v_t
    against its split along and across the axis) and its closed form g (sin a - mu cos a)
    to 1e-6 (tests/test_contact.py's bound)."""
    down = (0.0, 0.0, -1.0)
    directional = slide(down, directional_friction=(0.2, 0.2, 0.2))
    isotropic = slide(down, friction=0.2)
    z = [np.array([d["tip_position_z"] for d in rows]) for rows in (directional, isotropic)]
    assert np.max(np.abs(z[0] - z[1])) < 1e-9 * abs(z[1][-1] - z[1][0])
    assert acceleration(directional, "z") == pytest.approx(
        -G * (np.sin(A) - 0.2 * np.cos(A)), rel=1e-6)


@pytest.mark.mpi
@pytest.mark.parametrize("slope, axis, mu", [
    ((0.0, 0.0, 1.0), "z", FORWARD),        # down the slope towards the rod's end s = L
    ((0.0, 0.0, -1.0), "z", BACKWARD),      # towards its start
    ((0.0, -1.0, 0.0), "y", LATERAL)])      # across its axis
def test_a_rod_slides_down_an_incline_with_the_coefficient_of_its_direction(slope, axis, mu):
    """Coefficients forward 0.1, backward 0.3, lateral 0.04 (all < tan 30 deg: it
    slides): along the slope the tip accelerates at g (sin a - mu cos a) with the
    coefficient of the direction it slides in, to 1e-6 (tests/test_contact.py's bound:
    Coulomb's force is exact beyond the slip tolerance).  Across the slope the friction
    also spins the rod about its axis (it acts on the surface), but at mu < tan a / 6
    (m r^2 / J_3 = 5) its contact point keeps slipping: the same closed form."""
    rows = slide(slope, directional_friction=(FORWARD, BACKWARD, LATERAL))
    along = float(np.dot(slope, [1.0 if axis == c else 0.0 for c in "xyz"]))
    assert along * acceleration(rows, axis) == pytest.approx(
        G * (np.sin(A) - mu * np.cos(A)), rel=1e-6)
    assert min(d["friction_dissipation"] for d in rows) >= 0.0


def test_the_muscle_spline_is_pyelastica_s():
    """The amplitude's clamped cubic B-spline over sigma / L (TravellingWave.profile, in
    numpy; the UFL pieces are the same polynomials) is PyElastica's own of the same
    control values (elastica.external_forces._bspline, its continuum snake's six), to
    round-off (measured 2e-18 of 4e-3)."""
    forces = pytest.importorskip("elastica.external_forces")
    beta = np.array([3.4e-3, 3.3e-3, 4.2e-3, 2.6e-3, 3.6e-3, 3.5e-3])
    x = np.linspace(0.0, 1.0, 201)
    ours = TravellingWave((0.0, 1.0, 0.0), beta, 2.0, 0.35).profile(x)
    assert np.max(np.abs(ours - forces._bspline(beta)[0](x))) < 1e-15


WAVE = TravellingWave(axis=(1.0, 0.0, 0.0), amplitude=[0.3, 0.1, 0.5, 0.2, 0.4, 0.25],
                      period=2.0, wave_length=0.7, phase=0.3, ramp=0.5, origin="end")


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_a_muscle_wave_bends_a_rod_to_its_moment_over_the_stiffness(rotations):
    """A quasi-static cantilever (L = 1, EI = (2, 3), GJ = 4, 16 cells) under the
    travelling wave alone (spline amplitude, wave from the end s = L, ramped over 0.5 s):
    at rest m = M, so its curvature about the wave's axis e_1 (= d_1: the rod bends in
    its plane) is u_1 = M_1(s, t) / EI_1 at every cell's midpoint (the strains' 1-point
    rule), and u_2 = u_3 = 0, at t = 0.35, 0.8, 1.3 s (in the ramp and after, the wave
    at different phases); to 1e-8 of max |u_1| (Newton's tolerance; measured 5e-11)."""
    EI = (2.0, 3.0, 4.0)
    rod = RodModel(RodParameters(length=1.0, A=EI, B=(1e3, 1e3, 1e3)), n_cells=16,
                   model="hyperelastic", start="clamped", end="free", rotations=rotations,
                   distributed_loads=WAVE.loads(1.0))
    rod.set_initial_state()
    stepper = TimeStepper(rod.problem)
    s = rod.pointwise(ufl.SpatialCoordinate(rod.mesh)[0])[:, 0]    # owned midpoints
    previous = 0.0
    for t in (0.35, 0.8, 1.3):
        stepper.run(previous, t, min(0.05, t - previous))
        previous = t
        u = rod.pointwise(rod.u)
        expected = WAVE.moment(s, t, 1.0)[:, 0] / EI[0]
        scale = np.max(np.abs(expected))
        assert np.max(np.abs(u[:, 0] - expected)) < 1e-8 * scale
        assert np.max(np.abs(u[:, 1:])) < 1e-8 * scale


@pytest.mark.mpi
def test_two_muscles_of_other_numbers_share_their_kernels():
    """A muscle's numbers (spline control values, wave length, phase; the period and ramp
    are its histories') are Constants of the model (external_forces.WaveProfile): a
    second wave of other numbers gives a model of the same structure (rod/structure.py)
    and the same UFL residual signatures, so it reuses the first one's compiled kernels
    (a new muscle value compiled them anew: minutes on a loaded machine), and it bends the
    rod to its own moment (u_1 = M_1 / EI_1 at t = 0.8 s, to 1e-8 of max |u_1| as
    above)."""
    other = TravellingWave(axis=(1.0, 0.0, 0.0), amplitude=[0.1, 0.6, 0.2, 0.3, 0.5, 0.15],
                           period=1.5, wave_length=0.45, phase=-1.1, ramp=0.2, origin="end")
    EI = (2.0, 3.0, 4.0)
    rods = [RodModel(RodParameters(length=1.0, A=EI, B=(1e3, 1e3, 1e3)), n_cells=16,
                     model="hyperelastic", start="clamped", end="free",
                     distributed_loads=wave.loads(1.0)) for wave in (WAVE, other)]
    assert rods[0].problem.structure is not None
    assert rods[1].problem.structure == rods[0].problem.structure
    assert [f.signature() for f in rods[1].problem.residual] == \
        [f.signature() for f in rods[0].problem.residual]
    rod = rods[1]
    rod.set_initial_state()
    TimeStepper(rod.problem).run(0.0, 0.8, 0.05)
    s = rod.pointwise(ufl.SpatialCoordinate(rod.mesh)[0])[:, 0]
    expected = other.moment(s, 0.8, 1.0)[:, 0] / EI[0]
    assert np.max(np.abs(rod.pointwise(rod.u)[:, 0] - expected)) < 1e-8 * np.max(
        np.abs(expected))


SNAKE = (Path(__file__).resolve().parents[1] / "scenes" / "continuum_snake.toml").read_text()


@pytest.mark.parametrize("old, new, key", [
    (", lateral = 0.178456 }", " }", "obstacles[0].friction.lateral"),
    ("backward = 0.133842", "backward = -0.1", "obstacles[0].friction.backward"),
    ("friction = {", "friction = { sideways = 0.1,", "obstacles[0].friction.sideways"),
    ("period = 2.0 ", "", "loads.muscle.period"),
    ("amplitude = [3.4e-3, 3.3e-3, 4.2e-3, 2.6e-3, 3.6e-3, 3.5e-3]", "amplitude = [1.0, 2.0]",
     "loads.muscle.amplitude"),
    ("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 0.0, 0.0]", "loads.muscle.axis"),
    ("origin = \"end\"", "origin = \"head\"", "loads.muscle.origin"),
    ("wave_length = 0.35", "wave_length = 0.0", "loads.muscle.wave_length")])
def test_bad_snake_keys_are_named(old, new, key):
    """A wrong directional friction or muscle key: one SceneError naming it (exit 2 from
    the command line, as every SceneError)."""
    assert old in SNAKE
    with pytest.raises(SceneError) as err:
        parse_scene(SNAKE.replace(old, new))
    assert f"[{key}]" in str(err.value), str(err.value)


def test_directional_friction_on_segments_is_accepted():
    """A sphere whose barrier acts on the segments (contact = "segments") takes a
    directional table too (the segments' law: test_obstacle_segments.py
    test_directional_friction_on_thin_bars; it was refused)."""
    text = SNAKE.replace('shape = "plane"                     # the ground',
                         'shape = "sphere"\ncentre = [0.0, -0.1, 0.1]\nradius = 0.05\n'
                         'contact = "segments"\n#')
    text = text.replace("point = [0.0, -0.0040425, 0.0]\nnormal = [0.0, 1.0, 0.0]\n", "")
    ob = parse_scene(text)["obstacles"][0]
    assert ob["contact"] == "segments" and isinstance(ob["friction"], tuple)


PYELASTICA_FORWARD = 0.027832    # m/s, benchmarks/snake_peer.py --quick: dt = 5e-5 (1e-4: 0.027782)


@pytest.mark.slow
@pytest.mark.mpi
def test_the_continuum_snake_slithers_at_pyelastica_speed(tmp_path):
    """scenes/continuum_snake.toml for 4 periods (t_end = 8.02 s, dt = 2e-3, as bundled):
    its centre of mass's average forward speed over [2 T, 4 T] against PyElastica's
    run of its own example with the same parameters over the same window (converged in
    dt: 0.2 % between 1e-4 and 5e-5).  Measured 0.027751 m/s, 0.29 % below; it moves
    by 7e-5 relative with eps = 3e-4 instead of 1e-3 and by 3e-5 with dt = 1e-3:
    the rest is the codes' different discrete laws of the same friction (PyElastica's
    on its elements with a linear contact spring, this one's on the nodes with the
    barrier's normal force).  Asserted to 1 %, three times that difference."""
    from mpi4py import MPI

    from dolfin_rod import read_pvd, run
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))
    result = run(str(Path(__file__).resolve().parents[1] / "scenes" / "continuum_snake.toml"),
                 {"time.t_end": 8.02, "outputs.every": 5, "outputs.animation": False,
                  "outputs.plots": False, "outputs.progress": False,
                  "outputs.directory": str(folder)}, quiet=True)
    assert result.status == "completed", result.summary["message"]
    steps = read_pvd(result.folder / "rod.pvd")
    times = np.array([s["time"] for s in steps])
    w = np.full(51, 1.0)
    w[[0, -1]] = 0.5
    z = np.array([w @ s["points"][:, 2] / w.sum() for s in steps])    # the centre of mass
    a, b = (int(np.argmin(np.abs(times - t))) for t in (4.0, 8.0))
    forward = (z[b] - z[a]) / (times[b] - times[a])
    assert forward == pytest.approx(PYELASTICA_FORWARD, rel=1e-2)
