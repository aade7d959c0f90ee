"""Rod systems shared by tests/test_rod_system.py and the MPI case of cases.py."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from dolfin_rod import EndLoad, Rod, RodModel, RodParameters, RodSystem, TimeStepper
from dolfin_rod.theory.rotations import np_quaternion_from_rotation_vector, np_rotation_matrix

# Newton to round-off, so that the coupled solve stops where each rod's alone does
ROUND_OFF = {"snes_rtol": 1e-13, "snes_atol": 1e-13}
T_END, DT = 0.2, 0.02
A = RodParameters(length=1.0, density=1.0, section_inertia=0.01, M_d=(5, 5, 5), N_d=(5, 5, 5))
B = RodParameters(length=0.7, A=(2, 1.5, 1), B=(3, 3, 4), density=2.0,
                  section_inertia=(0.02, 0.01), M_d=(2, 2, 2), N_d=(2, 2, 2), reference_curvature=(0.3, 0, 0))
FORCE_A, COUPLE_B = (1.0, 0.0, 0.0), np.array((0.0, 0.5, 0.2))
POSITION_B, ORIENTATION_B = np.array([1.0, 2.0, 3.0]), np.array([0.3, np.pi / 2, 0.2])


def turn_b() -> np.ndarray:
    """The rotation matrix of rod b's orientation."""
    return np_rotation_matrix(np_quaternion_from_rotation_vector(ORIENTATION_B))


def two_rods(placed: bool, comm=MPI.COMM_WORLD) -> RodSystem:
    """Rod a (clamped, tip force) and rod b (pinned, its own material, reference
    curvature and cells, a tip couple); b moved to POSITION_B and, if ``placed``,
    turned by ORIENTATION_B (its dead couple turned with it)."""
    turn = turn_b() if placed else np.eye(3)
    return RodSystem([
        Rod(A, 6, end_loads=[EndLoad("force", FORCE_A)], name="a"),
        Rod(B, 5, "pinned", end_loads=[EndLoad("couple", tuple(turn @ COUPLE_B))],
            name="b", position=POSITION_B,
            orientation=ORIENTATION_B if placed else (0.0, 0.0, 0.0))], comm=comm)


def alone(which: str) -> RodModel:
    if which == "a":
        return RodModel(A, 6, end_loads=[EndLoad("force", FORCE_A)])
    return RodModel(B, 5, start="pinned", end="free", end_loads=[EndLoad("couple", COUPLE_B)])


def run_system(model, t_end: float = T_END, dt: float = DT) -> dict[str, float]:
    model.set_initial_state()
    TimeStepper(model.problem, solver_options=ROUND_OFF).run(0.0, t_end, dt)
    return model.diagnostics(t_end)


# -- joints (tests/test_joints.py) -------------------------------------------------------------

FRAME = dict(L1=1.0, L2=0.8, EI=2.0, EA=1e3, GA=5e2)


def l_frame(n_cells: int, force: float, steps_to_full_load: bool = False,
            comm=MPI.COMM_WORLD) -> RodSystem:
    """An L-shaped frame: a column along e_3 clamped at the origin, a beam along e_1 from
    its top, joined rigidly there; a dead force -force e_3 at the beam's tip (ramped over
    t in [0, 1] if ``steps_to_full_load``).  Hyperelastic, quasi-static."""
    from dolfin_rod import loads
    from dolfin_rod.rod.joints import Joint
    f = FRAME
    params = [RodParameters(length=length, A=(f["EI"], f["EI"], 1.5),
                            B=(f["GA"], f["GA"], f["EA"])) for length in (f["L1"], f["L2"])]
    history = loads.ramp(1.0, 1.0) if steps_to_full_load else (lambda t: 1.0)
    top = (0.0, 0.0, f["L1"])
    rods = [Rod(params[0], n_cells, name="column"),
            Rod(params[1], n_cells, "free", end="free", name="beam", position=top,
                orientation=(0.0, np.pi / 2, 0.0),
                end_loads=[EndLoad("force", (0.0, 0.0, -force), history)])]
    return RodSystem(rods, joints=[Joint("rigid", ("column", "beam"), top, name="knee")],
                     model="hyperelastic", comm=comm)


def solve_frame(n_cells: int, force: float, steps: int = 1, comm=MPI.COMM_WORLD) -> dict:
    """The frame's diagnostics at t = 1 (the load ramped in ``steps`` steps if > 1)."""
    model = l_frame(n_cells, force, steps > 1, comm)
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, 1.0, 1.0 / steps)
    return model.diagnostics(1.0)


PENDULUM = dict(g=9.81, rho_A=1.0, rho_I=1e-4, l1=1.0, l2=0.7, E=1e6, angles=(0.6, 1.1))


def double_pendulum(n_cells: int, comm=MPI.COMM_WORLD) -> RodSystem:
    """Two stiff rods (EA = k GA = E, EI = GJ = E/100) swinging in the x-z plane under
    gravity -g e_3: the upper one pinned at the origin, the lower one hung from its
    tip by a ball joint; at rest at t = 0 at the angles (from -e_3) of PENDULUM."""
    from dolfin_rod import DistributedLoad
    from dolfin_rod.rod.joints import Joint
    p = PENDULUM
    E, (a1, a2) = p["E"], p["angles"]
    gravity = [DistributedLoad("force", (0.0, 0.0, -p["rho_A"] * p["g"]))]
    params = [RodParameters(length=p[k], A=(E / 100,) * 3, B=(E,) * 3, density=p["rho_A"],
                            section_inertia=p["rho_I"]) for k in ("l1", "l2")]
    knee = p["l1"] * np.array([np.sin(a1), 0.0, -np.cos(a1)])
    rods = [Rod(params[0], n_cells, "pinned", end="free", distributed_loads=gravity,
                name="upper", orientation=(0.0, np.pi - a1, 0.0)),
            Rod(params[1], n_cells, "free", end="free", distributed_loads=gravity,
                name="lower", position=knee, orientation=(0.0, np.pi - a2, 0.0))]
    return RodSystem(rods, joints=[Joint("ball", ("upper", "lower"), knee)],
                     model="hyperelastic", comm=comm)


def rigid_double_pendulum(t_end: float, p: dict = PENDULUM, rates=(0.0, 0.0)):
    """The rigid double pendulum of two uniform rods (mass rho_A l, moment of inertia
    about the centre rho_A l^3/12 + rho_I l, the section's rotary inertia included):
    Lagrange's equations in the angles from -e_3, solved by solve_ivp to 1e-12
    (``p``: g, rho_A, rho_I, l1, l2, angles as PENDULUM; ``rates``: the angles' rates
    at t = 0)."""
    from scipy.integrate import solve_ivp
    g, l1, l2 = p["g"], p["l1"], p["l2"]
    m1, m2 = p["rho_A"] * l1, p["rho_A"] * l2
    I1 = m1 * l1 ** 2 / 12 + p["rho_I"] * l1
    I2 = m2 * l2 ** 2 / 12 + p["rho_I"] * l2
    c = m2 * l1 * l2 / 2

    def equations(t, y):
        a, b, wa, wb = y
        M = np.array([[m1 * l1 ** 2 / 4 + I1 + m2 * l1 ** 2, c * np.cos(a - b)],
                      [c * np.cos(a - b), m2 * l2 ** 2 / 4 + I2]])
        f = -np.array([c * np.sin(a - b) * wb ** 2 + (m1 / 2 + m2) * l1 * g * np.sin(a),
                       -c * np.sin(a - b) * wa ** 2 + m2 * l2 / 2 * g * np.sin(b)])
        return [wa, wb, *np.linalg.solve(M, f)]

    return solve_ivp(equations, (0.0, t_end), [*p["angles"], *rates], rtol=1e-12,
                     atol=1e-12, dense_output=True)


def pendulum_angles(d: dict) -> np.ndarray:
    """The angles from -e_3 of the two rods' chords (knee and tip positions)."""
    knee = np.array([d[f"upper.tip_position_{c}"] for c in "xyz"])
    tip = np.array([d[f"lower.tip_position_{c}"] for c in "xyz"])
    return np.array([np.arctan2(knee[0], -knee[2]),
                     np.arctan2(tip[0] - knee[0], -(tip[2] - knee[2]))])


def swing(model: RodSystem, t_end: float, dt: float) -> tuple[float, float]:
    """A double pendulum (``double_pendulum`` or one with another joint) released at
    rest and run to t_end: (the largest error of its chords' angles against the rigid
    ODE, the drift of K + Psi + rho_A g int z ds)."""
    exact = rigid_double_pendulum(t_end).sol(t_end)[:2]
    model.set_initial_state()
    energies = []

    def observe(t, _):
        d = model.diagnostics(t)
        energies.append(d["kinetic_energy"] + d["free_energy"] + gravity_potential(model))

    TimeStepper(model.problem).run(0.0, t_end, dt, observer=observe)
    error = np.abs(pendulum_angles(model.diagnostics(t_end)) - exact).max()
    return error, abs(energies[-1] - energies[0])


def gravity_potential(model) -> float:
    """rho_A g int z ds over both rods (serial): z = s + x_3 is P1, so the trapezoidal
    rule on the nodes is exact, as the 2-point Gauss rule of the load's work."""
    p = PENDULUM
    V = model.f["displacement"].function_space
    s = V.tabulate_dof_coordinates()[:, 0]
    z = s + model.f["displacement"].x.array.reshape(-1, 3)[:, 2]
    total = 0.0
    for k, rod in enumerate(model.rods):
        a, b = model.layout.span(k)
        h = rod.params.length / rod.n_cells
        on = (s > a - 1e-9) & (s < b + 1e-9)
        weights = np.where(np.isclose(s[on], a) | np.isclose(s[on], b), h / 2, h)
        total += weights @ z[on]
    return p["rho_A"] * p["g"] * total


DOOR = dict(g=9.81, rho_A=1.0, rho_I=1e-4, post=0.3, width=1.0, E=1e7, push=0.5)


def hinged_door(n_cells: int, comm=MPI.COMM_WORLD) -> RodSystem:
    """A door: a stiff post along e_3 clamped at the origin, a stiff rod along e_1 (the
    door) hung from its top by a hinge about e_3, under gravity -g e_3 (a smooth step
    over 0.1 s: no bending vibrations) and a dead force ``push`` e_2 at its free edge;
    at rest at t = 0 (DOOR; EA = k GA = E, EI = GJ = E/100)."""
    from dolfin_rod import DistributedLoad, loads
    from dolfin_rod.rod.joints import Joint
    p = DOOR
    E, top = p["E"], (0.0, 0.0, p["post"])
    gravity = [DistributedLoad("force", (0.0, 0.0, -p["rho_A"] * p["g"]),
                               loads.smooth_step(1.0, 0.1))]
    params = [RodParameters(length=p[k], A=(E / 100,) * 3, B=(E,) * 3, density=p["rho_A"],
                            section_inertia=p["rho_I"]) for k in ("post", "width")]
    rods = [Rod(params[0], n_cells, "clamped", end="free", name="post"),
            Rod(params[1], n_cells, "free", end="free", distributed_loads=gravity, name="door",
                position=top, orientation=(0.0, np.pi / 2, 0.0),
                end_loads=[EndLoad("force", (0.0, p["push"], 0.0))])]
    return RodSystem(rods, joints=[Joint("hinge", ("post", "door"), top, name="hinge",
                                         axis=(0.0, 0.0, 1.0))],
                     model="hyperelastic", comm=comm)


def door_angle(t_end: float, p: dict = DOOR):
    """The rigid door's angle about e_3: I phi'' = push L cos(phi), I = rho_A L^3/3 +
    rho_I L (the sections turn about their own axis e_3 too), at rest at 0 (solve_ivp,
    1e-12)."""
    from scipy.integrate import solve_ivp
    L = p["width"]
    inertia = p["rho_A"] * L ** 3 / 3 + p["rho_I"] * L
    return solve_ivp(lambda t, y: [y[1], p["push"] * L * np.cos(y[0]) / inertia],
                     (0.0, t_end), [0.0, 0.0], rtol=1e-12, atol=1e-12, dense_output=True)


def kinked_frame(n_column: int, n_beam: int, force: float, steps: int = 1,
                 joined: bool = False) -> dict:
    """The L-frame of ``l_frame`` with n_column, n_beam cells, tip force -force e_3
    (ramped over ``steps`` steps if > 1), at t = 1: as ONE rod of n_column + n_beam
    cells whose stress-free shape is the polyline through the clamp, the knee and the
    tip (the corner at a node, or between nodes where n_column : n_beam is not L1 : L2),
    or ``joined`` as the two rods and the rigid knee.  Diagnostics at t = 1, the tip as
    ``tip_position_*`` either way."""
    from dolfin_rod import loads
    from dolfin_rod.rod.joints import Joint
    from dolfin_rod.rod.start import Polyline
    f = FRAME
    L1, L2 = f["L1"], f["L2"]
    history = loads.ramp(1.0, 1.0) if steps > 1 else (lambda t: 1.0)
    load = [EndLoad("force", (0.0, 0.0, -force), history)]

    def params(length, shape=None):
        return RodParameters(length=length, A=(f["EI"], f["EI"], 1.5),
                             B=(f["GA"], f["GA"], f["EA"]), reference_shape=shape)

    if joined:
        top = (0.0, 0.0, L1)
        model = RodSystem([Rod(params(L1), n_column, name="column"),
                           Rod(params(L2), n_beam, "free", end="free", name="beam",
                               position=top, orientation=(0.0, np.pi / 2, 0.0),
                               end_loads=load)],
                          joints=[Joint("rigid", ("column", "beam"), top)],
                          model="hyperelastic")
    else:
        corner = Polyline(((0.0, 0.0, 0.0), (0.0, 0.0, L1), (L2, 0.0, L1)))
        model = RodModel(params(L1 + L2, corner), n_column + n_beam, model="hyperelastic",
                         end_loads=load)
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, 1.0, 1.0 / steps)
    d = model.diagnostics(1.0)
    return {k.removeprefix("beam."): v for k, v in d.items()}
