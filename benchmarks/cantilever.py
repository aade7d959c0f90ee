"""The peer-comparison scenes (issue 7), built identically in dolfin_rod and PyElastica.

Cantilever along e_3, clamped at s = 0, gravity along -e_1:
    L = 1, r = 0.025, rho = 1000, E = 1e6, G = E/1.5, g = 9.81, T = 0.5.
Section constants as PyElastica's ``CosseratRod.straight_rod``: A = pi r^2, I = pi r^4/4,
J = 2I, shear stiffness alpha_c G A with alpha_c = 27/28 (PyElastica 1.0,
rod/factory_function.py), so both codes discretise the same continuum:
    bending/torsion  (E I, E I, G J),  shear/axial  (alpha_c G A, alpha_c G A, E A),
    mass per length rho A, section inertia rho (I, I, 2I).

Scene "elastic": hyperelastic, undamped.  Scene "creep": the natural curvature and
stretch evolve by the local law (eqs. unatevol, vnatevol) with A_d = A, B_d = B,
M_d = tau A, N_d = tau B, i.e. per strain component
    d u_d/dt = (u - 2 u_d)/tau,    d (v_d - e_3)/dt = ((v - e_3) - 2 (v_d - e_3))/tau,
which on the PyElastica side is a forcing that updates rest_kappa and rest_sigma once
per step (forward Euler, as a PyElastica user would).

More gravity-cantilever variants (issue 12; same rod unless stated): "soft" (E / 3),
"stiff" (3 E), "long" (T = 2, about half a first-mode period), "oblique" (gravity
(-0.6, -0.48, 0.64) g: out-of-plane and with an axial, tensile part).  ``SCENES`` holds
them; PyElastica's step follows its wave-speed rule dt = 0.01 dx sqrt(E_0/E).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import elastica as ea
import numpy as np

L, RADIUS, RHO, E = 1.0, 0.025, 1000.0, 1e6
G = E / 1.5
GRAV = 9.81
T_END = 0.5
TAU = 0.1                       # creep time of the natural configuration
ALPHA_C = 27.0 / 28.0           # PyElastica 1.0 shear coefficient
AREA = np.pi * RADIUS**2
I_SEC = np.pi * RADIUS**4 / 4
J_SEC = 2 * I_SEC


@dataclass(frozen=True)
class Scene:
    name: str
    evolving: bool = False
    E: float = E
    T: float = T_END
    gravity: tuple = (-1.0, 0.0, 0.0)    # direction of g

    @property
    def G(self):
        return self.E / 1.5

    @property
    def samples(self):
        return np.linspace(self.T / 5, self.T, 5)

    @property
    def pyelastica_dt_factor(self):  # PyElastica dt = factor dx (explicit: wave speed)
        return 0.01 * np.sqrt(E / self.E)


SCENES = {sc.name: sc for sc in (
    Scene("elastic"), Scene("creep", evolving=True), Scene("soft", E=E / 3),
    Scene("stiff", E=3 * E), Scene("long", T=2.0),
    Scene("oblique", gravity=(-0.6, -0.48, 0.64)))}


def section_constants(scene: Scene):
    """(A, B) = ((E I, E I, G J), (alpha_c G A, alpha_c G A, E A))."""
    return ((scene.E * I_SEC, scene.E * I_SEC, scene.G * J_SEC),
            (ALPHA_C * scene.G * AREA, ALPHA_C * scene.G * AREA, scene.E * AREA))


def tip_error(tips, ref):
    """max over the sample times of |tip - tip_ref|, relative to max |tip_ref - tip_0|."""
    tips, ref = np.asarray(tips), np.asarray(ref)
    scale = np.max(np.linalg.norm(ref - np.array([0.0, 0.0, L]), axis=1))
    return float(np.max(np.linalg.norm(tips - ref, axis=1)) / scale)


# -- dolfin_rod ---------------------------------------------------------------------------

def dolfin_rod_parameters(scene: Scene):
    from dolfin_rod import DistributedLoad, RodParameters
    A, B = section_constants(scene)
    kw = {}
    if scene.evolving:
        kw = dict(A_d=A, B_d=B, M_d=tuple(TAU * a for a in A), N_d=tuple(TAU * b for b in B))
    params = RodParameters(length=L, A=A, B=B, density=RHO * AREA,
                           section_inertia=RHO * I_SEC, **kw)
    weight = DistributedLoad("force", tuple(RHO * AREA * GRAV * np.asarray(scene.gravity)))
    return params, "evolving" if scene.evolving else "hyperelastic", [weight]


def dolfin_rod_model(n_cells: int, scene: str, comm=None, rotations: str = "auto"):
    """RodModel of a scene; rotations "auto" (the default: rotation vectors for these
    dynamic rods) or "quaternion" (the previous default, for comparison)."""
    from mpi4py import MPI
    from dolfin_rod import RodModel
    params, model_name, loads = dolfin_rod_parameters(SCENES[scene])
    model = RodModel(params, n_cells=n_cells, model=model_name, variant="local",
                     start="clamped", end="free", distributed_loads=loads, rotations=rotations,
                     comm=comm or MPI.COMM_WORLD)
    model.set_initial_state()
    return model


class TipProbe:
    """Tip position r(L) = (0, 0, L) + x(L) from the owning rank (no form assembly)."""

    def __init__(self, model):
        import dolfinx.fem as fem
        V = model.f["displacement"].function_space
        dofs = fem.locate_dofs_geometrical(V, lambda X: np.isclose(X[0], L))
        n_owned = V.dofmap.index_map.size_local
        self.dofs = [d for d in dofs if d < n_owned]
        self.u = model.f["displacement"]
        self.comm = model.mesh.comm

    def __call__(self):
        val = np.zeros(3)
        if self.dofs:
            val = self.u.x.array[3 * self.dofs[0]: 3 * self.dofs[0] + 3].copy()
        if self.comm.size > 1:      # a buffer Allreduce: the pickled one costs ~20 us a
            from mpi4py import MPI  # call even on one rank, which PyElastica's tip read
            self.comm.Allreduce(MPI.IN_PLACE, val, op=MPI.SUM)      # does not pay
        return val + np.array([0.0, 0.0, L])


def run_dolfin_rod(n_cells: int, dt: float, scene: str, scheme: str | None = None,
                   options=None, comm=None, rotations: str = "auto",
                   tolerance: float | None = None) -> dict:
    """Tip positions at the scene's samples; set-up (model, stepper, step forms; JIT or
    cache load) and stepping timed apart.  scheme None, options None, rotations "auto":
    what a user gets by default (TimeStepper(model.problem)); ``tolerance``: its
    error-controlled steps (dt is then the first step)."""
    from dolfin_rod import TimeStepper
    t0 = time.perf_counter()
    model = dolfin_rod_model(n_cells, scene, comm, rotations)
    stepper = TimeStepper(model.problem, scheme, solver_options=options,
                          **({} if tolerance is None else {"tolerance": tolerance}))
    probe = TipProbe(model)
    stepper.compile()                          # compile the step forms before timing
    t1 = time.perf_counter()
    t, tips = 0.0, []
    for ts in SCENES[scene].samples:           # march to each sample exactly
        t = stepper.run(t, ts, dt, observer=None)
        tips.append(probe().tolist())
    t2 = time.perf_counter()
    return {"code": "dolfin_rod", "n_cells": n_cells, "dt": dt, "tolerance": tolerance,
            "rotations": model.rotations,
            "method": stepper.description, "setup_s": t1 - t0, "wall_s": t2 - t1,
            "steps": stepper.stats.steps, "newton_iterations": stepper.stats.newton_iterations,
            "rejected_steps": stepper.stats.rejected, "tips": tips}


# -- PyElastica ---------------------------------------------------------------------------


class NaturalConfigurationFlow(ea.NoForces):
    """d kappa0/dt = (kappa - 2 kappa0)/tau, d sigma0/dt = (sigma - 2 sigma0)/tau
    (the local evolution law with A_d = A, M_d = tau A, B_d = B, N_d = tau B)."""

    def __init__(self, tau):
        super().__init__()
        self.tau, self.t_last = tau, 0.0

    def apply_forces(self, system, time=0.0):
        h = float(time) - self.t_last
        if h <= 0.0:
            return
        self.t_last = float(time)
        system.rest_kappa += h / self.tau * (system.kappa - 2.0 * system.rest_kappa)
        system.rest_sigma += h / self.tau * (system.sigma - 2.0 * system.rest_sigma)


def run_pyelastica(n_elem: int, dt: float, scene: str) -> dict:
    sc = SCENES[scene]

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.CallBacks):
        pass

    t0 = time.perf_counter()
    sim = Sim()
    rod = ea.CosseratRod.straight_rod(
        n_elem, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]),
        L, RADIUS, RHO, youngs_modulus=sc.E, shear_modulus=sc.G)
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                             constrained_director_idx=(0,))
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=GRAV * np.asarray(sc.gravity))
    if sc.evolving:
        sim.add_forcing_to(rod).using(NaturalConfigurationFlow, tau=TAU)
    sim.finalize()
    stepper = ea.PositionVerlet()
    t1 = time.perf_counter()
    tips, t, steps = [], 0.0, 0
    for ts in sc.samples:
        n = int(round((ts - t) / dt))
        h = (ts - t) / n
        for _ in range(n):
            t = stepper.step(sim, t, h)
        t = float(ts)
        steps += n
        tips.append(rod.position_collection[:, -1].copy().tolist())
    t2 = time.perf_counter()
    return {"code": "pyelastica", "n_cells": n_elem, "dt": dt, "setup_s": t1 - t0,
            "wall_s": t2 - t1, "steps": steps, "tips": tips}
