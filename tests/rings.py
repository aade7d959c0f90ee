"""Closed rods (dolfin_rod/rod/ring.py) for tests/test_ring.py and its MPI cases: a ring
of length 1 (radius R = 1/(2 pi)), bending stiffness A = 1, twist stiffness C = A/1.3
(a round section of Poisson's ratio 0.3), shear and axial stiffness 1e5 (A/(B R^2) =
4e-4: nearly Kirchhoff's inextensible, unshearable rod)."""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from dolfin_rod import RodModel, RodParameters, StartingState, TimeStepper
from dolfin_rod.analysis.stability import StabilityMonitor
from dolfin_rod.output.line_fields import LineSampler
from dolfin_rod.rod.initial_state import settle

LENGTH, BEND, TWIST, STIFF = 1.0, 1.0, 1.0 / 1.3, 1e5
RADIUS = LENGTH / (2 * math.pi)
MICHELL = math.sqrt(3.0) * BEND / TWIST      # critical twist, turns (Michell 1889)
RING = RodParameters(length=LENGTH, A=(BEND, BEND, TWIST), B=(STIFF, STIFF, STIFF))


def ring(n_cells: int, link: float = 0.0, comm=MPI.COMM_WORLD, stiff: float = STIFF) -> RodModel:
    """The quasi-static ring clamped at its weld, closed with ``link`` turns of twist,
    settled in equilibrium (initial_state.settle: the twisted ring's shear is not in
    its start); ``stiff``: the shear and axial stiffness B."""
    params = RING if stiff == STIFF else RodParameters(
        length=LENGTH, A=(BEND, BEND, TWIST), B=(stiff, stiff, stiff))
    model = RodModel(params, n_cells, model="hyperelastic", closed=True, excess_link=link,
                     comm=comm)
    model.set_initial_state()
    if link:
        settle(model, 0.0)
    return model


def ring_fields(model) -> dict:
    """Energy, the weld's reactions, the nodes and the cells' internal force and couple
    (spatial), on every rank."""
    d = model.diagnostics(0.0)
    sample = LineSampler(model.mesh, model.observables(), point=("centre_line",)).sample()
    fields = None if sample is None else dict(
        n=sample.cell["n_spatial"].tolist(), m=sample.cell["m_spatial"].tolist(),
        centre=sample.point["centre_line"].tolist())
    return {"free_energy": d["free_energy"],
            "weld_force": [d[f"reaction_force_start_{c}"] for c in "xyz"],
            "weld_couple": [d[f"reaction_couple_start_{c}"] for c in "xyz"],
            **model.mesh.comm.bcast(fields)}


def michell_count(n_cells: int, link: float, comm=MPI.COMM_WORLD, stiff: float = STIFF) -> int:
    """The negative eigenvalues of the tangent stiffness of the settled ring (round-off
    zeros counted as zero: the isotropic ring's spin about its centre line is neutral)."""
    return StabilityMonitor(ring(n_cells, link, comm, stiff)).count(0.0)


def critical_link(n_cells: int, halvings: int = 16, stiff: float = STIFF) -> float:
    """The twist (turns) at which the count leaves 0, by bisection in [0.7, 1.3] x
    Michell's (2.7e-5 of it at 16 halvings)."""
    count = lambda link: michell_count(n_cells, link, stiff=stiff)    # noqa: E731
    lo, hi = 0.7 * MICHELL, 1.3 * MICHELL
    assert count(lo) == 0 and count(hi) > 0
    for _ in range(halvings):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if count(mid) else (mid, hi)
    return 0.5 * (lo + hi)


def free_ring(n_cells: int, link: float, comm=MPI.COMM_WORLD, push: float = 0.0,
              steps: int = 20, dt: float = 2e-3) -> dict:
    """A free dynamic ring (rho A = 1, rho J = 1e-4 I) closed with ``link`` turns, its
    nodes pushed along the ring's axis e_2 at ``push`` cos(2 phi) (phi = 2 pi s/L), run
    ``steps`` steps of dt: the diagnostics."""
    p = RodParameters(length=LENGTH, A=(BEND, BEND, TWIST), B=(1e4, 1e4, 1e4), density=1.0,
                      section_inertia=1e-4)
    model = RodModel(p, n_cells, model="hyperelastic", closed=True, excess_link=link,
                     start="free", comm=comm)
    model.set_initial_state(start=StartingState(velocity=lambda s: np.outer(
        push * np.cos(4 * np.pi * s / LENGTH), (0.0, 1.0, 0.0))))
    TimeStepper(model.problem).run(0.0, steps * dt, dt)
    return model.diagnostics(steps * dt)


def writhing_ring(n_cells: int, link: float, comm=MPI.COMM_WORLD, push: float = 2.0,
                  steps: int = 20, dt: float = 2e-3) -> list[tuple[float, float]]:
    """free_ring's ring with self-contact (radius 0.005: the twist and writhe columns,
    rod/ring.ring_linking) pushed hard out of its plane: (Tw, Wr) at the start and after
    each step."""
    from dolfin_rod.rod.contact import ContactLaw
    p = RodParameters(length=LENGTH, A=(BEND, BEND, TWIST), B=(1e4, 1e4, 1e4), density=1.0,
                      section_inertia=1e-4)
    model = RodModel(p, n_cells, model="hyperelastic", closed=True, excess_link=link,
                     start="free", comm=comm,
                     contact=ContactLaw(radius=0.005, gap=0.001, stiffness=1.0, self=True))
    model.set_initial_state(start=StartingState(velocity=lambda s: np.outer(
        push * np.cos(4 * np.pi * s / LENGTH), (0.0, 1.0, 0.0))))
    out = []

    def record(t, _):
        d = model.diagnostics(t)
        out.append((d["twist"], d["writhe"]))
    record(0.0, None)
    TimeStepper(model.problem).run(0.0, steps * dt, dt, record)
    return out


def _diameter(model, n_cells: int) -> np.ndarray:
    """From the weld (node 0) to the node at s = L/2, on every rank."""
    centre = np.array(ring_fields(model)["centre"])
    return centre[n_cells // 2] - centre[0]


def pulled_ring(n_cells: int, pull: float, stiff: float = 1e7, steps: int = 4,
                hold: int = 2) -> tuple[list[float], list[tuple[float, float]]]:
    """The quasi-static ring clamped at its weld, pulled at s = L/2 along the diameter
    from its weld by the dead force ``pull`` EI/R^2, ramped over t in [0, 1] in ``steps``
    steps and held for ``hold`` more (each a step from an equilibrium); ``stiff``: B.
    The diameter's change at the start and after each step, and after each step the
    residual norm at its solution with Newton's estimate of its round-off floor
    (BlockSNES.round_off_floor)."""
    from dolfin_rod.rod import PointLoad
    params = RodParameters(length=LENGTH, A=(BEND, BEND, TWIST), B=(stiff, stiff, stiff))
    start = RodModel(params, n_cells, model="hyperelastic", closed=True)
    start.set_initial_state()
    diameter = _diameter(start, n_cells)
    size = np.linalg.norm(diameter)
    force = pull * BEND / RADIUS ** 2 * diameter / size
    model = RodModel(params, n_cells, model="hyperelastic", closed=True, point_loads=[
        PointLoad("force", tuple(force), 0.5 * LENGTH, lambda t: min(t, 1.0))])
    model.set_initial_state()
    stepper = TimeStepper(model.problem)
    changes, floors = [], []

    def record(t, _):
        changes.append(float(_diameter(model, n_cells) @ diameter / size - size))
        if t > 0:
            floors.append((stepper.solver.snes.getFunctionNorm(),
                           stepper.solver.round_off_floor()))
    dt = 1.0 / steps
    stepper.run(0.0, 1.0 + hold * dt, dt, record)
    return changes, floors


def mechanism(n_cells: int, A: tuple = (BEND, BEND, TWIST)) -> dict:
    """The ring clamped at its weld, closed untwisted with bending stiffnesses A: the two
    lowest eigenvalues of its tangent stiffness (K v = lambda G v, LowestEigenvalues'
    metric) and, for the lowest, the largest difference of its mode from the mechanism
    of rod/ring.py (the rigid turn about the weld's tangent e_3, dx = e_3 x r, each
    section spinning back, material rotation R^T e_3 - E_3), both scaled to a largest
    displacement of 1 (on every rank)."""
    from dolfin_rod.analysis.eigen import eigenpairs
    from dolfin_rod.analysis.stability import LowestEigenvalues, TangentStiffness
    from dolfin_rod.rod.ring import Ring
    from dolfin_rod.theory.quaternions import np_rotation_matrix
    model = RodModel(RodParameters(length=LENGTH, A=A, B=(STIFF, STIFF, STIFF)), n_cells,
                     model="hyperelastic", closed=True, comm=MPI.COMM_WORLD)
    model.set_initial_state()
    tangent = TangentStiffness(model)
    K = tangent.matrix(0.0)
    pairs = eigenpairs(K, LowestEigenvalues(tangent).G, 2, target=0.0)
    K.destroy()
    shape = tangent.mode_shapes(pairs.vectors[:1])[0]
    s = model.f["displacement"].function_space.tabulate_dof_coordinates()[:, 0]
    r, q = Ring(0.0).frames(s, LENGTH, n_cells)
    e3 = np.array([0.0, 0.0, 1.0])
    dx = np.cross(e3, r)
    turn = np.array([np_rotation_matrix(qi).T @ e3 for qi in q]) - e3
    size = model.mesh.comm.allreduce(float(np.abs(dx).max(initial=0.0)), op=MPI.MAX)
    got_x = shape["displacement"].reshape(-1, 3)[:len(s)]
    got_t = shape["rotation"].reshape(-1, 3)[:len(s)]
    sign = np.sign(model.mesh.comm.allreduce(float(np.sum(got_x * dx)), op=MPI.SUM))
    misfit = max(float(np.abs(sign * got_x - dx / size).max(initial=0.0)),
                 float(np.abs(sign * got_t - turn / size).max(initial=0.0)))
    return {"values": sorted(float(v) for v in pairs.values),
            "misfit": model.mesh.comm.allreduce(misfit, op=MPI.MAX)}


def swinging_ring(n_cells: int, direction: int, drag: float, t_end: float = 4.0,
                  dt: float = 0.1, comm=MPI.COMM_WORLD) -> list:
    """The quasi-static ring clamped at its weld (B = 1e5, untwisted), pulled at s = L/2
    by the dead force e_direction (EI/L^2), with linear drag ``drag`` (0: none), run to
    t_end: the node at s = L/2 at the end (on every rank)."""
    from dolfin_rod.rod.external_forces import PointLoad
    force = np.eye(3)[direction]
    model = RodModel(RodParameters(length=LENGTH, A=(BEND, BEND, TWIST),
                                   B=(STIFF, STIFF, STIFF), drag=drag), n_cells,
                     model="hyperelastic", closed=True, comm=comm,
                     point_loads=[PointLoad("force", force, 0.5 * LENGTH)])
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, t_end, dt)
    return ring_fields(model)["centre"][n_cells // 2]


# the pinched ring of scenes/pinched_ring.toml (tests/test_pinched_ring.py): R = 1, EI = 1,
# EA = 1e4, GA = 0.886 EA/2.6, stress-free as its circle; P = 1e-3 at s = pi R
PINCHED = RodParameters(length=2 * math.pi, A=(1.0, 1.0, 1 / 1.3),
                        B=(3407.6923076923076, 3407.6923076923076, 1e4),
                        reference_curvature=(0.0, 1.0, 0.0))
PINCH = 1e-3


def pinched_in_system(n_cells: int, system: bool) -> float:
    """delta/P of the pinched ring clamped at its weld (quasi-static, one step to the
    equilibrium under +-P): alone (RodModel) or (``system``) as the second rod of a
    RodSystem, after a cantilever of 8 cells, placed at (3, 0, 0)."""
    from dolfin_rod import Rod, RodSystem
    from dolfin_rod.rod.external_forces import EndLoad, PointLoad
    moved = []
    for sign in (-1.0, 1.0):
        loads = [PointLoad("force", (sign * PINCH, 0.0, 0.0), math.pi)]
        if system:
            beam = Rod(RodParameters(length=1.0, B=(1e4, 1e4, 1e4)), 8, name="beam",
                       end_loads=[EndLoad("force", (1e-3, 0.0, 0.0))])
            model = RodSystem([beam, Rod(PINCHED, n_cells, name="ring", closed=True,
                                         point_loads=loads, position=(3.0, 0.0, 0.0))],
                              model="hyperelastic")
        else:
            model = RodModel(PINCHED, n_cells, model="hyperelastic", closed=True,
                             point_loads=loads)
        key = "ring.point0_position_x" if system else "point0_position_x"
        model.set_initial_state()
        start = model.diagnostics(0.0)[key]
        TimeStepper(model.problem).run(0.0, 1.0, 1.0)
        moved.append(model.diagnostics(1.0)[key] - start)
    return (moved[1] - moved[0]) / (2 * PINCH)


def free_ring_in_system(n_cells: int, link: float, push: float, steps: int = 20,
                        dt: float = 2e-3) -> dict:
    """free_ring's ring as the second rod of a RodSystem, after a dynamic cantilever of 8
    cells at rest, the ring placed at (2, 0, 0): the diagnostics."""
    from dolfin_rod import Rod, RodSystem
    p = RodParameters(length=LENGTH, A=(BEND, BEND, TWIST), B=(1e4, 1e4, 1e4), density=1.0,
                      section_inertia=1e-4)
    model = RodSystem([Rod(p, 8, name="beam"),
                       Rod(p, n_cells, name="ring", closed=True, excess_link=link,
                           start="free", position=(2.0, 0.0, 0.0))], model="hyperelastic")
    model.set_initial_state(start={"ring": StartingState(velocity=lambda s: np.outer(
        push * np.cos(4 * np.pi * s / LENGTH), (0.0, 1.0, 0.0)))})
    TimeStepper(model.problem).run(0.0, steps * dt, dt)
    return model.diagnostics(steps * dt)


def hanging_ring(n_cells: int, weight: float = 1.0) -> dict:
    """A free ring (B = 1e4, rho A = 1, drag 1) of weight ``weight`` (dead, -e_3) hanging
    by a ball joint at its node s = L/2 from the tip of a cantilever of 8 cells pointing
    down from the origin (tip at (0, 0, -1)), settled in equilibrium and run 10 steps of
    0.01: the diagnostics."""
    from dolfin_rod import Rod, RodSystem
    from dolfin_rod.rod.external_forces import DistributedLoad
    from dolfin_rod.rod.joint_points import Joint
    p = RodParameters(length=LENGTH, A=(BEND, BEND, TWIST), B=(1e4, 1e4, 1e4), density=1.0,
                      section_inertia=1e-4, drag=1.0)
    radius = LENGTH / (2 * n_cells * math.sin(math.pi / n_cells))     # the n-gon's
    beam = Rod(p, 8, name="beam", orientation=(math.pi, 0.0, 0.0))
    # the ring's d1 (towards its centre) turned to +e_3: its node at L/2, (2 R, 0, 0) in
    # its own frame, on top at the hook
    ring = Rod(p, n_cells, name="ring", closed=True, start="free",
               position=(0.0, 0.0, -1.0 - 2 * radius), orientation=(0.0, -math.pi / 2, 0.0),
               distributed_loads=[DistributedLoad("force", (0.0, 0.0, -weight / LENGTH))])
    model = RodSystem([beam, ring], [Joint("ball", ("beam", "ring"), (0.0, 0.0, -1.0),
                                           name="hook")], model="hyperelastic")
    model.set_initial_state(start={"ring": StartingState(equilibrium=True)})
    TimeStepper(model.problem).run(0.0, 0.1, 0.01)
    return model.diagnostics(0.1)
