"""dolfin_rod as a solver of cosseratbench, the open benchmark of Cosserat rod simulators
(issue 25 item 7; ``pip install 'dolfin_rod[bench]'``).

Registered through the entry point group ``cosseratbench.solvers`` (pyproject.toml), so

    cosseratbench run cantilever catenary pendulum twist crossing capstan pile \
        --solver dolfin_rod

scores dolfin_rod next to PyElastica and MuJoCo.  How a scenario is mapped:

- each rod: a RodModel of the hyperelastic quadratic energy with the section constants
  of its circle and material (rod/sections.py: A = (EI, EI, GJ), B = (k GA, k GA, EA),
  Cowper's shear factor), n_elements cells, its centre line as the starting polyline
  with its rest arc lengths and normal (rod/start.py; the stress-free shape straight);
  ends free / pinned / clamped, a driven clamp as prescribed end displacement and
  rotation (the Motion's piecewise-linear rotation vector), ``slides_along`` as a
  sliding end; point loads as dead end forces, gravity as the weight rho A g;
- obstacles (contact.py): a Cylinder or Plane as the obstacle of the same shape and
  friction with its surface moved back by ``OFFSET`` = delta / 2 (the barrier's gap
  delta = radius / 10), so that a rod starting on the surface (the capstan's rope)
  starts half-way into the barrier, not at its pole: cosseratbench's contact surface
  is reached where the barrier's gap is delta / 2 and its penetration measure reads
  (delta / 2 - g) / radius, within +-0.05 radii; the barrier's stiffness the larger of
  the rod and time step's (``default_stiffness``) and the one whose force at delta / 2
  carries the obstacle's pressure (``pressure``), friction with a slip tolerance of
  1e-3 L per duration (a rope held by friction creeps less than that);
- contact between rods and self-contact (pair_contact.py, pair_friction.py): rods that
  start within reach of each other (``in_reach``: the crossing ropes) run as one
  RodSystem with ``between_rods`` contact, other rods alone (the twist experiment's
  six rods 0.25 m apart: independent rods of one system give the same numbers); the
  scenario's ``self_contact`` as the law's (the pile's rope, the twist's rods); the
  rods' ``friction`` as the pairs' Coulomb coefficient; the same barrier gap radius /
  10 and stiffness rule as for obstacles (a rod's weight per length as the pressure);
  the rods' starting chords at least the gap apart (``apart``);
- with any contact: generalized-alpha with rho_inf = 0 (a barrier's impacts damped,
  docs/contact.md), Newton to rtol 1e-8, with friction a backtracking line search
  (scenes/contact.py's choices) and FRICTION_STEPS times more steps; a quasi-static
  rod that starts on an obstacle with friction (the capstan's rope), or rods that start
  within reach of each other (the crossing's), start with zero accelerations
  (``held_at_rest``: the starting state's ``acceleration = "zero"``, a scene's
  ``initial.acceleration``);
- a driven end's Motion (piecewise linear) turns at a step's end, never inside a step
  (``pieces``: the pile's feeding clamp stopping);
- dynamics: generalized-alpha on the rotation group (dolfin_rod's default), at most
  ``STEPS_PER_PERIOD`` steps per period of the scenario's slowest mode and at least one
  per frame; a quasi-static scenario adds damping proportional to mass at the rate
  2 omega (omega = ``Scenario.slowest_frequency``, critical damping of the slowest mode,
  PyElastica's choice): drag 2 omega rho A and rotational drag 2 omega rho J, so that
  the twist experiment's growth law s^2 + c s = a (twist - critical) holds.

What the adapter does not map raises ``NotImplementedError`` naming it (``unsupported``):
rods of different radii or friction coefficients within reach of each other (one
contact law per model).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from cosseratbench.scenario import End, EndCondition, Motion, Rod, Scenario
from cosseratbench.solver import Capability, Diverged
from cosseratbench.trajectory import Trajectory

from .. import __version__

STEPS_PER_PERIOD = 100      # time steps per period of the slowest mode (at least)
FRICTION_STEPS = 4          # times more with friction on an obstacle (the capstan's rope at
                            # mu = 0.6 failed its first step at 100 per period, not at 400)
FRICTION_NEWTON_ITERATIONS = 100   # Newton's limit with friction (solver_options)
OFFSET = 0.5                # obstacles' surfaces moved back by OFFSET barrier gaps
ENDS = {End.START: "start", End.END: "end"}


class DolfinRodSolver:
    """A cosseratbench solver adapter (cosseratbench.solver.Solver)."""

    name = "dolfin_rod"
    backend_version = __version__
    capabilities = frozenset({Capability.STRETCH, Capability.SHEAR, Capability.ROD_CONTACT,
                              Capability.ROD_FRICTION, Capability.CYLINDER_CONTACT,
                              Capability.PLANE_CONTACT})

    def __init__(self, time_step_scale: float = 1.0) -> None:
        self.time_step_scale = float(time_step_scale)

    def settings(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> dict:
        """The numerical choices of a run (recorded by cosseratbench with its result)."""
        dt, _ = self.time_step(scenario, n_frames)
        rho_inf = 0.0 if in_contact(scenario) else 0.8
        chosen = {"integrator": f"generalized-alpha on the rotation group (rho_inf = {rho_inf})",
                  "time_step": dt, "damping_rate": damping_rate(scenario),
                  "unknowns": "rotation vectors, 6 per node"}
        if in_contact(scenario):
            radius = min(rod.radius for rod in scenario.rods)
            chosen.update({"barrier_gap": radius / 10, "obstacle_offset": OFFSET * radius / 10})
        return chosen

    def time_step(self, scenario: Scenario, n_frames: int) -> tuple[float, int]:
        """(dt, steps per frame): STEPS_PER_PERIOD per period of the slowest mode (times
        FRICTION_STEPS with friction on an obstacle), times ``time_step_scale``, at least
        one step per frame."""
        frame = scenario.duration / (n_frames - 1)
        steps = STEPS_PER_PERIOD * (FRICTION_STEPS if with_friction(scenario) else 1)
        limit = self.time_step_scale * 2 * math.pi / (steps * scenario.slowest_frequency())
        steps = max(1, math.ceil(frame / limit))
        return frame / steps, steps

    def run(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> Trajectory:
        reason = unsupported(scenario)
        if reason:
            raise NotImplementedError(reason)
        times = np.linspace(0.0, scenario.duration, n_frames)
        dt, _ = self.time_step(scenario, n_frames)
        if touching(scenario):
            runs = run_model(scenario, system_model(scenario, n_elements, dt), times, dt)
        else:
            runs = [run_model(scenario, rod_model(scenario, rod, n_elements, dt), times,
                              dt)[0] for rod in scenario.rods]
        return Trajectory(times, tuple(p for p, _ in runs), tuple(d for _, d in runs))


def unsupported(scenario: Scenario) -> str | None:
    """What of ``scenario`` the adapter cannot map, or None: rods of different radii or
    friction coefficients touching each other (one ContactLaw per model)."""
    rods = scenario.rods if touching(scenario) else ()
    for key in ("radius", "friction"):
        if len({getattr(rod, key) for rod in rods}) > 1:
            return (f"rods of different {key} within reach of each other: not mapped by "
                    "the dolfin_rod adapter (one contact law per model)")
    return None


def touching(scenario: Scenario) -> bool:
    """Whether two rods start within reach of each other (``in_reach``): then all rods
    run as one RodSystem with contact between them."""
    rods = scenario.rods
    return any(in_reach(a, b) for k, a in enumerate(rods) for b in rods[k + 1:])


def in_contact(scenario: Scenario) -> bool:
    """Whether anything of ``scenario`` touches: obstacles, rods, a rod itself."""
    return bool(scenario.obstacles) or scenario.self_contact or touching(scenario)


def with_friction(scenario: Scenario) -> bool:
    """Whether friction acts: on an obstacle, or between segments in contact."""
    return (any(ob.friction > 0 for ob in scenario.obstacles)
            or ((scenario.self_contact or touching(scenario))
                and any(rod.friction > 0 for rod in scenario.rods)))


def in_reach(a: Rod, b: Rod) -> bool:
    """Whether the starting centre lines of ``a`` and ``b`` come within a tenth of the
    shorter rod's length (plus both radii) of each other: bounding boxes, then points."""
    from scipy.spatial import cKDTree
    p, q = (np.asarray(rod.centerline, float) for rod in (a, b))
    reach = 0.1 * min(a.length, b.length) + a.radius + b.radius
    if np.any(p.min(0) - reach > q.max(0)) or np.any(q.min(0) - reach > p.max(0)):
        return False
    return bool(cKDTree(q).query(p, distance_upper_bound=reach)[0].min() < reach)


def damping_rate(scenario: Scenario) -> float:
    """2 omega of the slowest mode for a quasi-static scenario, else 0."""
    return 2.0 * scenario.slowest_frequency() if scenario.quasi_static else 0.0


def section(rod: Rod, scenario: Scenario) -> dict:
    """RodParameters' section, material and damping keywords of ``rod`` (module
    docstring)."""
    from ..rod.sections import Material, circle, section_parameters
    m = rod.material
    constants = section_parameters(circle(rod.radius), Material(
        m.youngs_modulus, shear_modulus=m.shear_modulus, density=m.density))
    rate = damping_rate(scenario)
    I11, I22 = constants["section_inertia"]
    J = (I22, I11, I11 + I22)   # rho J
    damping = {"drag": rate * constants["density"],
               "rotational_drag": tuple(rate * j for j in J)} if rate else {}
    return {"length": rod.length, **constants, **damping}


def rod_data(scenario: Scenario, rod: Rod, n_elements: int, name: str = "rod"):
    """rods.Rod of ``rod``: parameters, cells, ends, motions, loads."""
    from ..rod import DistributedLoad, EndLoad, RodParameters
    from ..rod.rods import Rod as RodData
    params = RodParameters(**section(rod, scenario))
    gravity = np.asarray(scenario.gravity, float)
    loads = [DistributedLoad("force", tuple(params.density * gravity))] if gravity.any() \
        else []
    motions = {"end_displacement": {}, "end_rotation": {}, "end_slide": {}}
    for end, side in ENDS.items():
        motion = rod.motion(end)
        if motion is not None:
            motions["end_displacement"][side] = lambda t, mo=motion: mo.pose(t)[0]
            motions["end_rotation"][side] = lambda t, mo=motion: rotation_vector(mo, t)
            if motion.slides_along is not None:
                motions["end_slide"][side] = tuple(motion.axis)
    data = RodData(params, n_elements, start=rod.condition(End.START).value,
                   end=rod.condition(End.END).value,
                   end_loads=[EndLoad("force", tuple(load.force), end=ENDS[load.at])
                              for load in rod.loads],
                   distributed_loads=loads, name=name,
                   **{key: value or None for key, value in motions.items()})
    return data


def starting_state(rod: Rod, n_elements: int, params, pressed=None, nodes=None):
    """The rod's StartingState: its centre line at the n_elements + 1 nodes (Rod.nodes,
    or ``nodes``), the nodes moved by ``pressed(nodes, params)`` (``barrier_start``) with
    obstacles."""
    from ..rod import Polyline, StartingState
    nodes = rod.nodes(n_elements) if nodes is None else nodes
    if pressed is not None:
        nodes = pressed(nodes, params)
    return StartingState(shape=Polyline(tuple(map(tuple, nodes)),
                                        rest_arc_length=tuple(np.linspace(0.0, rod.length,
                                                                          n_elements + 1)),
                                        normal=tuple(rod.normal)))


def barrier_start(scenario: Scenario, obstacles: list, law):
    """nodes, params -> nodes: each node that starts within the barrier's reach of an
    obstacle moved along the obstacle's normal to the gap at which the barrier carries
    what the rod presses on it with at the start (its weight and the pull of its
    stretched neighbours: the rod as a string, its bending neglected), so that a rod
    starting at rest on an obstacle (the capstan's rope, in equilibrium as it hangs)
    starts in equilibrium with the barrier too, not with a jolt."""
    from ..rod.contact import NP_OPS, Pose, signed_distance
    poses = [Pose(ob) for ob in obstacles]

    def gaps(points):
        return np.stack([signed_distance(pose, points, NP_OPS) for pose in poses]) \
            - law.radius

    def pressed(nodes, params):
        rest = params.length / (len(nodes) - 1)
        weights = np.full(len(nodes), rest)                 # the trapezoidal rule's
        weights[[0, -1]] /= 2
        g = gaps(nodes)
        nearest = (np.argmin(g, axis=0), np.arange(len(nodes)))
        step = 1e-7 * law.radius
        normal = np.stack([(gaps(nodes + step * e)[nearest] - gaps(nodes - step * e)[nearest])
                           / (2 * step) for e in np.eye(3)], axis=1)
        carried = -np.einsum("ij,ij->i", string_load(nodes, params, scenario.gravity),
                             normal) / weights
        touching = g[nearest] < law.gap
        moved = nodes.copy()
        moved[touching] += ((equilibrium_gap(carried[touching], law) - g[nearest][touching])
                            [:, None] * normal[touching])
        return moved
    return pressed


def string_load(nodes: np.ndarray, params, gravity) -> np.ndarray:
    """The force on each node of a string through ``nodes`` (rest length params.length,
    axial stiffness EA = params.B[2], weight rho_A g per length, trapezoidal rule)."""
    rest = params.length / (len(nodes) - 1)
    chords = np.diff(nodes, axis=0)
    lengths = np.linalg.norm(chords, axis=1)
    pull = (params.B[2] * (lengths / rest - 1.0) / lengths)[:, None] * chords
    load = np.zeros_like(nodes)
    load[:-1] += pull
    load[1:] -= pull
    weights = np.full(len(nodes), rest)
    weights[[0, -1]] /= 2
    return load + weights[:, None] * params.density * np.asarray(gravity, float)


def equilibrium_gap(carried: np.ndarray, law) -> np.ndarray:
    """The gap g in (0, delta] at which the barrier's force kappa (-b'(g)) is ``carried``
    (per length; delta where it is <= 0), by bisection on [XI_MIN delta, delta]."""
    from ..rod.contact import XI_MIN, barrier_derivatives
    low, high = np.full(carried.shape, XI_MIN * law.gap), np.full(carried.shape, law.gap)
    for _ in range(60):
        middle = (low + high) / 2
        weak = -law.stiffness * barrier_derivatives(middle, law.gap)[1] < carried
        low, high = np.where(weak, low, middle), np.where(weak, middle, high)
    return (low + high) / 2


def obstacles(scenario: Scenario, gap: float) -> list:
    """contact.py's obstacles of the scenario's, their surfaces moved back by OFFSET gap."""
    from ..rod.contact import Obstacle
    back = OFFSET * gap
    return [Obstacle("cylinder", centre=tuple(ob.center), axis=tuple(ob.unit_axis),
                     radius=ob.radius - back, length=ob.length, friction=ob.friction)
            if ob.kind == "cylinder" else
            Obstacle("plane", point=tuple(np.asarray(ob.point) - back * ob.unit_normal),
                     normal=tuple(ob.unit_normal), friction=ob.friction)
            for ob in scenario.obstacles]


def contact_law(scenario: Scenario, rods, params, n_elements: int, dt: float):
    """The ContactLaw of ``rods`` (one, or the rods of a system; their parameters
    ``params``) touching the scenario's obstacles, themselves if it asks for
    self-contact, each other if they are several (module docstring)."""
    from ..rod.contact import ContactLaw, barrier_derivatives, default_stiffness
    radius, mu = rods[0].radius, rods[0].friction
    gap = radius / 10
    stiffness = max(max(default_stiffness(p.density, p.A, rod.length, n_elements, dt),
                        pressure(scenario, rod, p)
                        / -barrier_derivatives(OFFSET * gap, gap)[1])
                    for rod, p in zip(rods, params))
    pairs = len(rods) > 1
    return ContactLaw(radius, gap, stiffness,
                      slip_tolerance=1e-3 * min(rod.length for rod in rods) / scenario.duration,
                      self=scenario.self_contact, between_rods=pairs,
                      self_friction=mu if scenario.self_contact else 0.0,
                      between_rods_friction=mu if pairs else 0.0)


def pressure(scenario: Scenario, rod: Rod, params) -> float:
    """The force per length the obstacles carry, at most: the rod's weight rho A g on a
    floor (or on another rod), its whole weight's tension rho A g L over the radius R
    of a cylinder it hangs over (the capstan's rope)."""
    radii = [ob.radius for ob in scenario.obstacles if ob.kind == "cylinder"]
    weight = params.density * float(np.linalg.norm(scenario.gravity))
    return weight * max(1.0, rod.length / min(radii)) if radii else weight


def solver_options(scenario: Scenario) -> dict:
    """Newton's options with contact (scenes/contact.contact_solver_options' choices);
    on several ranks MUMPS (block Jacobi's GMRES failed the capstan's first step:
    DIVERGED_LINEAR_SOLVE)."""
    from mpi4py import MPI
    if not in_contact(scenario):
        return {}
    options = {"snes_rtol": 1e-8}
    if MPI.COMM_WORLD.size > 1:
        options.update(ksp_type="preonly", pc_type="lu", pc_factor_mat_solver_type="mumps")
    if with_friction(scenario):
        # bt's steps stay >= 0.1 of the last: where Newton crosses from the sliding to
        # the sticking branch of the friction law the residual falls by ~0.9 per
        # iteration (the capstan at mu = 0.6, 0.5 h2*: from 5e7 to 4 in 25; docs/contact.md)
        options.update(snes_linesearch_type="bt", snes_max_it=FRICTION_NEWTON_ITERATIONS)
    return options


def rod_model(scenario: Scenario, rod: Rod, n_elements: int, dt: float):
    """(the RodModel of one rod of ``scenario``, its StartingState; module docstring)."""
    from ..rod import RodModel
    data = rod_data(scenario, rod, n_elements)
    touches, pressed = contact(scenario, [rod], [data.params], n_elements, dt)
    model = RodModel(data.params, n_cells=n_elements, model="hyperelastic",
                     start=data.start, end=data.end, end_loads=data.end_loads,
                     distributed_loads=data.distributed_loads,
                     end_displacement=data.end_displacement or {},
                     end_rotation=data.end_rotation or {},
                     end_slide=data.end_slide or {}, **touches)
    return model, starting_state(rod, n_elements, data.params, pressed)


def system_model(scenario: Scenario, n_elements: int, dt: float):
    """(the RodSystem of all rods of ``scenario`` with contact between them, their
    StartingStates by name)."""
    from ..rod.system import RodSystem
    data = [rod_data(scenario, rod, n_elements, f"rod{k}")
            for k, rod in enumerate(scenario.rods)]
    params = [d.params for d in data]
    touches, pressed = contact(scenario, scenario.rods, params, n_elements, dt)
    model = RodSystem(data, model="hyperelastic", **touches)
    nodes = apart([rod.nodes(n_elements) for rod in scenario.rods], touches["contact"])
    return model, {d.name: starting_state(rod, n_elements, d.params, pressed, start)
                   for d, rod, start in zip(data, scenario.rods, nodes)}


APART_PASSES = 20           # passes of ``apart`` (the crossing at 13 elements: one moves
                            # its middle chords 1.58 mm each, the next finds none near)


def apart(nodes: list[np.ndarray], law) -> list[np.ndarray]:
    """The rods' starting ``nodes`` with the chords of different rods at least the
    barrier's gap delta apart (surface to surface), so that they start outside each
    other's barrier (the crossing at 13 elements: its ropes' middle chords, coarse chords
    of sagging curves that touch, overlapped by 2.66 mm, and the model refused the start,
    PairOverlap): the two segments of each pair nearer than that moved apart along
    their closest points' line by half the deficit each, their rods' end nodes kept
    (held by the ends' conditions), until no pair is (RuntimeError after
    APART_PASSES passes)."""
    from ..rod.segments import closest_points
    nodes = [np.array(n, float) for n in nodes]
    least = 2 * law.radius + law.gap
    for _ in range(APART_PASSES):
        moved = False
        for a in range(len(nodes)):
            for b in range(a + 1, len(nodes)):
                i, j = (m.ravel() for m in np.meshgrid(np.arange(len(nodes[a]) - 1),
                                                        np.arange(len(nodes[b]) - 1)))
                p, q = nodes[a], nodes[b]
                s, t, d = closest_points(p[i], p[i + 1], q[j], q[j + 1])
                near = d < least * (1 - 1e-9)
                for k in np.flatnonzero(near):
                    x = p[i[k]] + s[k] * (p[i[k] + 1] - p[i[k]])
                    y = q[j[k]] + t[k] * (q[j[k] + 1] - q[j[k]])
                    shift = (least - d[k]) / 2 * (x - y) / d[k]
                    for rod, first, sign in ((p, i[k], 1.0), (q, j[k], -1.0)):
                        inner = [m for m in (first, first + 1) if 0 < m < len(rod) - 1]
                        rod[inner] += sign * shift
                moved = moved or bool(near.any())
        if not moved:
            return nodes
    raise RuntimeError(f"the rods' starting chords stay nearer than the barrier's gap "
                       f"after {APART_PASSES} passes (dolfin_rod adapter: apart)")


def contact(scenario: Scenario, rods, params, n_elements: int, dt: float):
    """({"obstacles", "contact"} keywords of the model, the starting nodes' ``pressed``
    or None) of ``rods``: nothing if nothing touches."""
    if not (scenario.obstacles or scenario.self_contact or len(rods) > 1):
        return {}, None
    law = contact_law(scenario, rods, params, n_elements, dt)
    found = obstacles(scenario, law.gap)
    return ({"obstacles": found, "contact": law},
            barrier_start(scenario, found, law) if found else None)


def rotation_vector(motion: Motion, t: float) -> np.ndarray:
    """The Motion's rotation vector at t, interpolated linearly as Motion.pose does."""
    i, f = _segment(motion.times, t)
    r = np.asarray(motion.rotation, float)
    return r[i] + f * (r[i + 1] - r[i])


def _segment(times, t: float) -> tuple[int, float]:
    """(interval index, fraction in [0, 1]) of t in the increasing ``times``; after the
    last, the end of the last interval (the Motion holds still)."""
    if t >= times[-1]:
        return len(times) - 2, 1.0
    i = int(np.searchsorted(times, t, side="right")) - 1
    return i, (t - times[i]) / (times[i + 1] - times[i])


def run_model(scenario: Scenario, built, times: np.ndarray, dt: float) -> list:
    """[(positions [T, n + 1, 3], directors [T, n, 3]) of each rod] of ``built`` (a
    model and its starting state) at ``times``."""
    from ..integrators.step_control import IntegrationError
    from ..integrators.choice import TimeStepper
    model, start = built
    model.set_initial_state(start=start)
    if held_at_rest(scenario, model):
        model.set_initial_state(start=at_rest(start))
    scheme = "generalized_alpha:0.0" if in_contact(scenario) else None
    stepper = TimeStepper(model.problem, scheme, solver_options(scenario))
    frames = [frame(model)]
    knots = motion_knots(scenario)
    try:
        for t0, t1 in zip(times[:-1], times[1:]):
            for a, b in pieces(float(t0), float(t1), knots, dt):
                stepper.run(a, b, dt)
            frames.append(frame(model))
    except IntegrationError as err:
        raise Diverged(f"dolfin_rod: {err}", time=getattr(err, "t", None)) from err
    return [(np.stack([f[k][0] for f in frames]), np.stack([f[k][1] for f in frames]))
            for k in range(len(frames[0]))]


def motion_knots(scenario: Scenario) -> np.ndarray:
    """The times at which a driven end's piecewise-linear Motion turns (its velocity
    jumps: the pile's feeding clamp stopping), sorted."""
    return np.unique([t for rod in scenario.rods for end in ENDS
                      if (motion := rod.motion(end)) is not None for t in motion.times])


def pieces(t0: float, t1: float, knots: np.ndarray, dt: float) -> list[tuple[float, float]]:
    """[t0, t1] cut at the ``knots`` inside it (those within round-off of dt of an end
    taken as that end), so that the steps end where a Motion turns.  A step with a turn
    inside it is refused by loads.resolution_problem once the turn lies early in it (the
    end's velocity would jump within the step: cosseratbench's pile at
    time_step_scale 4, its clamp stopping 0.08 dt into a step); the step that ends on it
    follows the Motion exactly, at one more step per turn at most."""
    from ..integrators.step_control import ROUND_OFF
    margin = ROUND_OFF * dt
    inside = knots[(knots > t0 + margin) & (knots < t1 - margin)]
    bounds = [t0, *map(float, inside), t1]
    return list(zip(bounds[:-1], bounds[1:]))


def held_at_rest(scenario: Scenario, model) -> bool:
    """Whether ``model`` (in its starting state) begins at rest: a quasi-static scenario
    (the question is whether an equilibrium exists: the solver may damp its way to it)
    whose rod starts within the barrier's gap of an obstacle with friction (held by
    friction: the capstan's rope, placed by ``barrier_start``; not the pile's, lowered
    from above the floor) or whose rods start within reach of each other (``touching``:
    the crossing's ropes, whose starting centre lines are not the discrete rods'
    equilibrium: 2.2e6 rad/s^2 and 583 m/s^2 at t = 0 at 27 elements; the first step's
    predictor h^2 / 2 a0 moved them by 0.45 mm (the barrier's gap: 0.5 mm) and 1.7 rad at
    h = 1.25 ms, and at cosseratbench's time_step_scale 4 (dt = 0.08 s) the first step
    failed after 6 cuts, where it needed 7)."""
    if not scenario.quasi_static:
        return False
    if touching(scenario):
        return True
    if not any(ob.friction > 0 for ob in scenario.obstacles):
        return False
    return model.diagnostics(0.0)["min_gap"] < model.contact.law.gap


def at_rest(start):
    """The starting state(s) ``start`` (a StartingState, or {rod name: StartingState})
    with zero accelerations (a rod ``held_at_rest``).  Solved from the balance laws, the
    starting accelerations are those of a start that is not the discrete equilibrium
    (the capstan's hanging rope starts unstretched, the crossing's ropes
    2.2e6 rad/s^2 and 583 m/s^2 at 27 elements); generalized-alpha (rho_inf = 0) carries
    them into the first steps' velocities, which friction reads as slip: the rope at
    mu = 0.3, 0.8 h2* slid 8.2 mm at cosseratbench's time_step_scale 4 (7.1 mm with
    friction read at the first step's slip, the default start; 0.39 mm from rest), at
    mu = 0.6 the first step failed (docs/contact.md), and every capstan run cut its first
    steps 3-11 times."""
    if isinstance(start, dict):
        return {name: replace(one, acceleration="zero") for name, one in start.items()}
    return replace(start, acceleration="zero")


def frame(model) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(nodal positions in order of s, d1 of each element: R e1 of the normalised mean
    of its end nodes' quaternions) of each rod], gathered from every rank."""
    x = model.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    r = x.x.array.reshape(-1, 3) + np.outer(s, [0.0, 0.0, 1.0])
    q = model.unknowns.chart.q_n.x.array.reshape(-1, 4)
    gathered = model.mesh.comm.allgather((s, r, q))
    s, r, q = (np.concatenate([g[i] for g in gathered]) for i in range(3))
    s, index = np.unique(s, return_index=True)
    r, q = r[index], q[index]
    spans = [model.layout.span(k) for k in range(len(model.layout.lengths))]
    return [rod_frame(r[mine], q[mine])
            for mine in ((s >= a - 1e-12) & (s <= b + 1e-12) for a, b in spans)]


def rod_frame(r: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(r, d1 of each element) of one rod's nodes r and quaternions q."""
    from ..theory.rotations import np_rotation_matrix
    a, b = q[:-1], q[1:] * np.sign(np.einsum("ij,ij->i", q[:-1], q[1:]))[:, None]
    mid = (a + b) / np.linalg.norm(a + b, axis=1)[:, None]
    return r, np.array([np_rotation_matrix(m)[:, 0] for m in mid])
