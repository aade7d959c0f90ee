"""dolfin_rod as a solver of cosseratbench, the open benchmark of Cosserat rod simulators
(issue 25 item 7; ``pip install 'dolfin_rod[bench]'``).

Registered through the entry point group ``cosseratbench.solvers`` (pyproject.toml), so

    cosseratbench run cantilever catenary pendulum twist --solver dolfin_rod

scores dolfin_rod next to PyElastica and MuJoCo.  How a scenario is mapped:

- each rod: a RodModel of the hyperelastic quadratic energy with the section constants
  of its circle and material (rod/sections.py: A = (EI, EI, GJ), B = (k GA, k GA, EA),
  Cowper's shear factor), n_elements cells, its centre line as the starting polyline
  with its rest arc lengths and normal (rod/start.py; the stress-free shape straight);
  ends free / pinned / clamped, a driven clamp as prescribed end displacement and
  rotation (the Motion's piecewise-linear rotation vector), ``slides_along`` as a
  sliding end; point loads as dead end forces, gravity as the weight rho A g;
- the rods of a scenario do not touch (no contact is claimed): each runs alone (the
  twist experiment's six rods; independent rods of one system give the same numbers);
- dynamics: generalized-alpha on the rotation group (dolfin_rod's default), at most
  ``STEPS_PER_PERIOD`` steps per period of the scenario's slowest mode and at least one
  per frame; a quasi-static scenario adds damping proportional to mass at the rate
  2 omega (omega = ``Scenario.slowest_frequency``, critical damping of the slowest mode,
  PyElastica's choice): drag 2 omega rho A and rotational drag 2 omega rho J, so that
  the twist experiment's growth law s^2 + c s = a (twist - critical) holds.

What the adapter does not map raises ``NotImplementedError`` naming it: obstacles
(cylinders, planes), friction between rods.
"""

from __future__ import annotations

import math

import numpy as np
from cosseratbench.scenario import End, EndCondition, Motion, Rod, Scenario
from cosseratbench.solver import Capability, Diverged
from cosseratbench.trajectory import Trajectory

from .. import __version__

STEPS_PER_PERIOD = 100      # time steps per period of the slowest mode (at least)
ENDS = {End.START: "left", End.END: "right"}


def unsupported(scenario: Scenario) -> str | None:
    """What of ``scenario`` the adapter cannot map, or None."""
    if scenario.obstacles:
        kinds = sorted({type(o).__name__.lower() for o in scenario.obstacles})
        return (f"obstacles ({', '.join(kinds)}): contact with fixed obstacles is not mapped "
                "by the dolfin_rod adapter")
    if len(scenario.rods) > 1 and any(rod.friction for rod in scenario.rods):
        return "friction between rods: dolfin_rod has no rod-rod contact"
    return None


class DolfinRodSolver:
    """A cosseratbench solver adapter (cosseratbench.solver.Solver)."""

    name = "dolfin_rod"
    backend_version = __version__
    capabilities = frozenset({Capability.STRETCH, Capability.SHEAR})

    def __init__(self, time_step_scale: float = 1.0) -> None:
        self.time_step_scale = float(time_step_scale)

    def settings(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> dict:
        """The numerical choices of a run (recorded by cosseratbench with its result)."""
        dt, _ = self.time_step(scenario, n_frames)
        return {"integrator": "generalized-alpha on the rotation group (rho_inf = 0.8)",
                "time_step": dt, "damping_rate": damping_rate(scenario),
                "unknowns": "rotation vectors, 6 per node"}

    def time_step(self, scenario: Scenario, n_frames: int) -> tuple[float, int]:
        """(dt, steps per frame): STEPS_PER_PERIOD per period of the slowest mode, times
        ``time_step_scale``, at least one step per frame."""
        frame = scenario.duration / (n_frames - 1)
        limit = self.time_step_scale * 2 * math.pi / (STEPS_PER_PERIOD *
                                                      scenario.slowest_frequency())
        steps = max(1, math.ceil(frame / limit))
        return frame / steps, steps

    def run(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> Trajectory:
        reason = unsupported(scenario)
        if reason:
            raise NotImplementedError(reason)
        times = np.linspace(0.0, scenario.duration, n_frames)
        dt, _ = self.time_step(scenario, n_frames)
        runs = [run_rod(scenario, rod, n_elements, times, dt) for rod in scenario.rods]
        return Trajectory(times, tuple(p for p, _ in runs), tuple(d for _, d in runs))


def damping_rate(scenario: Scenario) -> float:
    """2 omega of the slowest mode for a quasi-static scenario, else 0."""
    return 2.0 * scenario.slowest_frequency() if scenario.quasi_static else 0.0


def rod_model(scenario: Scenario, rod: Rod, n_elements: int):
    """The RodModel of one rod of ``scenario`` (module docstring) and its StartingState."""
    from ..rod import DistributedLoad, EndLoad, Polyline, RodModel, RodParameters, StartingState
    from ..rod.sections import Material, circle, section_parameters
    m = rod.material
    section = section_parameters(circle(rod.radius), Material(
        m.youngs_modulus, shear_modulus=m.shear_modulus, density=m.density))
    rate = damping_rate(scenario)
    I11, I22 = section["section_inertia"]
    J = (I22, I11, I11 + I22)   # rho J
    damping = {"drag": rate * section["density"],
               "rotational_drag": tuple(rate * j for j in J)} if rate else {}
    params = RodParameters(length=rod.length, **section, **damping)
    gravity = np.asarray(scenario.gravity, float)
    loads = [DistributedLoad("force", tuple(section["density"] * gravity))] if gravity.any() \
        else []
    motions = {"end_displacement": {}, "end_rotation": {}, "end_slide": {}}
    for end, side in ENDS.items():
        motion = rod.motion(end)
        if motion is not None:
            motions["end_displacement"][side] = lambda t, mo=motion: mo.pose(t)[0]
            motions["end_rotation"][side] = lambda t, mo=motion: rotation_vector(mo, t)
            if motion.slides_along is not None:
                motions["end_slide"][side] = tuple(motion.axis)
    model = RodModel(params, n_cells=n_elements, model="hyperelastic",
                     start=rod.condition(End.START).value,
                     end=rod.condition(End.END).value,
                     end_loads=[EndLoad("force", tuple(load.force), end=ENDS[load.at])
                                for load in rod.loads],
                     distributed_loads=loads, **motions)
    start = StartingState(shape=Polyline(tuple(map(tuple, rod.centerline)),
                                         rest_arc_length=rod.rest_arc_length,
                                         normal=tuple(rod.normal)))
    return model, start


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


def run_rod(scenario: Scenario, rod: Rod, n_elements: int, times: np.ndarray, dt: float):
    """(positions [T, n + 1, 3], directors [T, n, 3]) of one rod at ``times``."""
    from ..integrators.step_control import IntegrationError
    from ..integrators.choice import TimeStepper
    model, start = rod_model(scenario, rod, n_elements)
    model.set_initial_state(start=start)
    stepper = TimeStepper(model.problem)
    frames = [frame(model)]
    try:
        for t0, t1 in zip(times[:-1], times[1:]):
            stepper.run(float(t0), float(t1), dt)
            frames.append(frame(model))
    except IntegrationError as err:
        raise Diverged(f"dolfin_rod: {err}", time=getattr(err, "t", None)) from err
    return np.stack([p for p, _ in frames]), np.stack([d for _, d in frames])


def frame(model) -> tuple[np.ndarray, np.ndarray]:
    """Nodal positions in order of s and d1 of each element (R e1 of the normalised mean
    of its end nodes' quaternions), gathered from every rank."""
    from ..theory.rotations import np_rotation_matrix
    x = model.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    r = x.x.array.reshape(-1, 3) + np.outer(s, [0.0, 0.0, 1.0])
    q = model.unknowns.chart.q_n.x.array.reshape(-1, 4)
    gathered = model.mesh.comm.allgather((s, r, q))
    s, r, q = (np.concatenate([g[i] for g in gathered]) for i in range(3))
    s, index = np.unique(s, return_index=True)
    r, q = r[index], q[index]
    a, b = q[:-1], q[1:] * np.sign(np.einsum("ij,ij->i", q[:-1], q[1:]))[:, None]
    mid = (a + b) / np.linalg.norm(a + b, axis=1)[:, None]
    d1 = np.array([np_rotation_matrix(m)[:, 0] for m in mid])
    return r, d1
