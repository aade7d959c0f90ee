"""The start of a dynamic rod (integrators/lie_alpha.py initial_accelerations, rod/start.py
``acceleration``, the scene's ``initial.acceleration``; docs/contact.md, "Starting
accelerations"): a rod at rest on an obstacle with friction starts with the
accelerations friction allows, not the frictionless ones.

References: a rigid body at rest on an incline (mu > tan a: it stays at rest, the
smoothed law lets it creep at y eps < eps, so its displacement stays below eps t; mu <
tan a: it slides from rest at g (sin a - mu cos a), its displacement g (sin a - mu cos a)
t^2 / 2 from the first step on); generalized-alpha's first step from a given algorithmic
acceleration (Chung & Hulbert 1993) for a body in free fall.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters, StartingState
from dolfin_rod.rod.barrier import barrier_derivatives
from dolfin_rod.rod.contact import ContactLaw, Obstacle, default_stiffness
from dolfin_rod.scenes import SceneError, parse_scene

G, R, DELTA, EPS = 9.81, 0.01, 1e-3, 1e-4
ROD = RodParameters(length=1.0, A=(1e-2, 1e-2, 1e-2), B=(10.0, 10.0, 10.0), density=1.0,
                    section_inertia=1e-5)
OPTIONS = {"snes_rtol": 1e-10, "snes_atol": 1e-12, "snes_linesearch_type": "bt"}


def _on_incline(angle: float, mu: float, dt: float) -> RodModel:
    """A free rod (8 cells) lying at rest on the plane x = -(r + g0), gravity tilted by
    ``angle`` degrees from its normal, friction ``mu``, slip tolerance EPS, the default
    barrier stiffness of dt: g0 is the gap at which the barrier carries the weight's
    normal part rho_A g cos a (every node the same share), so that only friction
    decides how the rod starts."""
    a = np.radians(angle)
    kappa = default_stiffness(ROD.density, ROD.A, ROD.length, 8, dt)
    g0 = brentq(lambda g: -kappa * barrier_derivatives(g, DELTA)[1] - G * np.cos(a),
                1e-6 * DELTA, (1 - 1e-9) * DELTA)
    plane = Obstacle("plane", point=(-(R + g0), 0.0, 0.0), normal=(1.0, 0.0, 0.0),
                     friction=mu)
    rod = RodModel(ROD, n_cells=8, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad(
                       "force", (-G * np.cos(a), 0.0, -G * np.sin(a)))],
                   obstacles=[plane], contact=ContactLaw(R, DELTA, kappa, slip_tolerance=EPS))
    rod.set_initial_state()
    return rod


def _slide(rod: RodModel, dt: float, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(times, the tip's displacement down the slope) after each of n_steps steps."""
    stepper = TimeStepper(rod.problem, "generalized_alpha:0.0", OPTIONS)
    z0 = rod.diagnostics(0.0)["tip_position_z"]
    t, dz = [], []
    for k in range(n_steps):
        stepper.run(k * dt, (k + 1) * dt, dt)
        t.append((k + 1) * dt)
        dz.append(z0 - rod.diagnostics((k + 1) * dt)["tip_position_z"])
    return np.array(t), np.array(dz)


@pytest.mark.mpi
def test_rod_held_by_friction_starts_at_rest():
    """mu = 0.8 > tan 30 deg, dt = 0.1 s: the rod stays at rest from the first step, its
    displacement below the smoothed law's creep bound eps t at every step (measured
    2.7e-6 m after the first step, 1.0e-4 m after 2 s: y eps t, y = 0.53).  From the
    frictionless starting accelerations (g sin a down the slope, carried into the first
    velocities) the first step failed after 6 cuts."""
    t, dz = _slide(_on_incline(30.0, 0.8, 0.1), 0.1, 20)
    assert np.all(np.abs(dz) < EPS * t), dz


@pytest.mark.mpi
def test_rod_starts_sliding_at_coulomb_from_the_first_step():
    """mu = 0.2 < tan 30 deg, dt = 0.01 s: from rest the rod slides at g (sin a - mu cos a)
    from the first step, its displacement g (sin a - mu cos a) t^2 / 2 at every step to
    1e-9 (measured 1.5e-13).  From the frictionless starting
    accelerations the steps carried half a step's frictionless excess in their velocity
    (0.5 h mu g cos a = 8.5 mm/s): 1.6 % ahead at 0.3 s."""
    a = np.radians(30.0)
    t, dz = _slide(_on_incline(30.0, 0.2, 0.01), 0.01, 30)
    exact = 0.5 * G * (np.sin(a) - 0.2 * np.cos(a)) * t**2
    assert dz == pytest.approx(exact, rel=1e-9)     # Newton: rtol 1e-10 of each step


@pytest.mark.mpi
@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_rod_laid_within_the_barrier_rests_on_it(dt):
    """A free rod laid at rest at delta / 2 above a plane (friction 0.3), under gravity
    along the plane's normal, with the default barrier stiffness of dt: it starts at the
    gap g* where the barrier carries its weight, kappa (-b'(g*)) = rho_A g (a root of
    the barrier's closed form: 0.862 delta at dt = 1e-3, 0.188 delta at 1e-2), and the
    plane's force is the weight from the first step on, to 1e-4 (measured 8e-6: the
    start's moves stop below 1e-6 delta).  Before, at dt = 1e-3 the barrier at delta / 2
    pushed with 19 times the weight: the rod was thrown up to 4 delta, the plane's force
    between 0 and 17 W over 0.1 s; at dt = 1e-2 it sank, the force between 0.57 and 1.7 W."""
    kappa = default_stiffness(ROD.density, ROD.A, ROD.length, 8, dt)
    plane = Obstacle("plane", point=(-(R + 0.5 * DELTA), 0.0, 0.0), normal=(1.0, 0.0, 0.0),
                     friction=0.3)
    rod = RodModel(ROD, n_cells=8, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad("force", (-G, 0.0, 0.0))],
                   obstacles=[plane], contact=ContactLaw(R, DELTA, kappa, slip_tolerance=1e-3))
    rod.set_initial_state()
    stepper = TimeStepper(rod.problem, "generalized_alpha:0.0", OPTIONS)
    resting = brentq(lambda g: -kappa * barrier_derivatives(g, DELTA)[1] - G * ROD.density,
                     1e-6 * DELTA, (1 - 1e-9) * DELTA)
    for k in range(int(round(0.1 / dt))):
        stepper.run(k * dt, (k + 1) * dt, dt)
        d = rod.diagnostics((k + 1) * dt)
        assert d["contact_force_x"] == pytest.approx(G * ROD.density * ROD.length, rel=1e-4)
        assert d["min_gap"] == pytest.approx(resting, abs=1e-5 * DELTA)


FALLING = """
[material]
model = "hyperelastic"
stiffness = { A = [1e-2, 1e-2, 1e-2], B = [10.0, 10.0, 10.0] }
density = 1.0
section_inertia = 1e-5
[geometry]
n_cells = 4
[boundary]
start = "free"
end = "free"
[loads]
gravity = [-9.81, 0.0, 0.0]
[time]
t_end = 0.01
dt = 0.01
[outputs]
fields = false
animation = false
plots = false
"""


@pytest.mark.mpi
@pytest.mark.parametrize("start", ["balance", "zero"])
def test_scene_chooses_the_starting_accelerations(tmp_path, start):
    """A free rod falling from rest, one step h of generalized-alpha (rho_inf = 0.8:
    alpha_m = 1/3, alpha_f = 4/9, beta = (1/2 + alpha_f - alpha_m)^2 / 4), run as the CLI
    runs a scene.  With ``initial.acceleration = "balance"`` (the default) it starts at
    -g and falls g h^2 / 2, exactly; with "zero" its first algorithmic acceleration is
    (1 - alpha_f) / (1 - alpha_m) g (the filter from a_0 = 0) and it falls
    beta (1 - alpha_f) / (1 - alpha_m) g h^2 = 0.257 g h^2."""
    from mpi4py import MPI

    from dolfin_rod import run
    text = FALLING + ("" if start == "balance" else '[initial]\nacceleration = "zero"\n')
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0)) / "run"
    result = run(parse_scene(text), out=folder, quiet=True)
    assert result.status == "completed", result.summary["message"]
    fall = -np.array(result.series["tip_position_x"], float)[-1]
    am, af = 1 / 3, 4 / 9
    beta = (0.5 + af - am + 0.5) ** 2 / 4
    h = 0.01
    expected = 0.5 * G * h * h if start == "balance" else beta * (1 - af) / (1 - am) * G * h * h
    assert fall == pytest.approx(expected, rel=1e-9)     # Newton: rtol 1e-10


@pytest.mark.mpi
def test_adaptive_steps_start_from_zero_starting_accelerations(tmp_path):
    """The adaptive stepper's error estimate of a step, h^2 c (a_1 - a_0), after a start
    whose accelerations were set to 0 (initial.acceleration = "zero") measures the start's
    imbalance, not the step's truncation error: it falls only as h^2, and a polyline's
    corners (scenes/overhand_knot_tie.toml, rotational accelerations ~1e8 rad/s^2) had
    the first step cut six times and the run fail at t = 0.  That first step is now
    taken as a fixed step is: the free rod above, falling from rest at tolerance 1e-7
    (where the estimate of its first step of 0.01 s is ~10^3 times the tolerance), takes
    its first step of dt = 0.01 s and falls beta (1 - alpha_f) / (1 - alpha_m) g h^2, the
    fixed step's closed form (above; Newton: rtol 1e-10), then goes on error-controlled."""
    from mpi4py import MPI

    from dolfin_rod import run
    text = (FALLING.replace("t_end = 0.01", "t_end = 0.03\nadaptive = true\ntolerance = 1e-7")
            + '[initial]\nacceleration = "zero"\n')
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0)) / "run"
    result = run(parse_scene(text), out=folder, quiet=True)
    assert result.status == "completed", result.summary["message"]
    h = 0.01
    assert result.series["time"][1] == pytest.approx(h, rel=1e-12)
    am, af = 1 / 3, 4 / 9
    beta = (0.5 + af - am + 0.5) ** 2 / 4
    fall = -float(result.series["tip_position_x"][1])
    assert fall == pytest.approx(beta * (1 - af) / (1 - am) * G * h * h, rel=1e-9)


QUASI_STATIC = [("density = 1.0\nsection_inertia = 1e-5\n", ""),
                ("[loads]\ngravity = [-9.81, 0.0, 0.0]\n", ""),
                ('start = "free"', 'start = "clamped"')]


@pytest.mark.parametrize("changes", [QUASI_STATIC, [("[geometry]\n",
                                                    '[geometry]\nrotations = "quaternion"\n')]],
                         ids=["quasi-static", "quaternions"])
def test_zero_starting_accelerations_need_a_dynamic_rod_with_rotation_vectors(changes):
    """initial.acceleration = "zero" on a quasi-static rod (no accelerations) or a
    quaternion rod (its schemes start from the state alone) is refused naming the key;
    an unknown value too."""
    text = FALLING
    for old, new in changes:
        text = text.replace(old, new)
    for scene in (text + '[initial]\nacceleration = "zero"\n',
                  FALLING + '[initial]\nacceleration = "rest"\n'):
        with pytest.raises(SceneError, match=r"initial\.acceleration"):
            parse_scene(scene)
