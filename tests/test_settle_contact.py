"""A start settled in static equilibrium in contact (rod/initial_state.py settle,
_settle_in_pseudo_time; the scene's ``initial.equilibrium``; docs/contact.md, "A start in
equilibrium in contact"): the rod travels to the obstacles it has to reach.

References: linear beam theory of a cantilever propped at its tip (the prop's force
R = 3 EI / L^3 (q L^4 / (8 EI) - Delta) at the tip's deflection Delta); a straight rod
lying on a plane (every node carries its share of the weight: the barrier's gap is the
one at which -kappa b'(g) = rho_A g, rod/contact.carrying_gap, the same at every node);
the equilibrium reached by an independent path (a quasi-static rod whose weight is
ramped from 0 over load steps: the same static equations); a free rod on a frictionless
slope has no static equilibrium.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters, StartingState
from dolfin_rod.rod.contact import ContactLaw, Obstacle, carrying_gap, default_stiffness
from dolfin_rod.scenes import SceneError, parse_scene
from test_starting_accelerations import FALLING

G, R = 9.81, 0.01


def _rod(params, n_cells, ends, below, delta, load=(-G, 0.0, 0.0), history=lambda t: 1.0,
         rotations="auto"):
    """A rod along e_3 with the weight ``load`` per length over a frictionless plane whose
    surface lies ``below`` under the rod's (x = -(below + r)), the default barrier
    stiffness of 16 cells at dt = 1e-2."""
    kappa = default_stiffness(1.0, params.A, params.length, 16, 1e-2)
    return RodModel(params, n_cells=n_cells, model="hyperelastic", start=ends[0], end=ends[1],
                    rotations=rotations,
                    distributed_loads=[DistributedLoad("force", load, history)],
                    obstacles=[Obstacle("plane", point=(-(below + R), 0.0, 0.0),
                                        normal=(1.0, 0.0, 0.0))],
                    contact=ContactLaw(R, delta, kappa)), kappa


def _settled(rod):
    rod.set_initial_state(start=StartingState(equilibrium=True))
    return rod.diagnostics(0.0)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_cantilever_settles_propped_on_a_plane_below_it(rotations):
    """A clamped cantilever (EI = 50, L = 1, weight q = 9.81 N/m, 32 cells) whose free
    deflection q L^4 / (8 EI) = 24.5 mm reaches past a plane 10 mm below it (one Newton
    solve from the straight start lands deep in the barrier and fails): settled, its tip
    rests on the plane with the propped cantilever's force 3 EI / L^3 (q L^4 / (8 EI) -
    Delta), Delta the tip's deflection (beam theory; slopes ~ 0.02 make the rod's
    geometric nonlinearity ~ 4e-4 of it; the shear and axial stiffness 1e8 make their
    compliance negligible).  Measured error 9.3e-4, 1.9e-4, 1.3e-5 at 16, 32, 64 cells
    (the discretisation's h^2): asserted 4e-4 at 32; both rotation unknowns give the same
    state (the same equations)."""
    EI = 50.0
    params = RodParameters(length=1.0, A=(EI, EI, EI), B=(1e8, 1e8, 1e8), density=1.0,
                           section_inertia=1e-5)
    rod, _ = _rod(params, 32, ("clamped", "free"), 0.01, 1e-4, rotations=rotations)
    d = _settled(rod)
    deflection = -d["tip_position_x"]
    assert 0.01 - 1e-4 < deflection < 0.01           # resting within the barrier's gap
    prop = 3 * EI * (G / (8 * EI) - deflection)
    assert d["contact_force_x"] == pytest.approx(prop, rel=4e-4)


@pytest.mark.mpi
def test_cantilever_far_above_a_plane_settles_as_the_quasi_static_load_path():
    """The cantilever of the refused scene before (EI = 5, free deflection 0.25 m, the
    plane 0.1 m below, 16 cells): settled in pseudo-time it is the equilibrium that a
    quasi-static rod (density 0: the same static equations) reaches by its weight ramped
    from 0 over 20 load steps, tip and plane force to Newton's tolerance (both stop at
    residuals <= 1e-10 N; measured 1.3e-13 m and 6.7e-10 of the force: asserted 1e-11 m
    and 1e-8)."""
    params = RodParameters(length=1.0, A=(5.0, 5.0, 5.0), B=(1e4, 1e4, 1e4), density=1.0,
                           section_inertia=1e-5)
    rod, _ = _rod(params, 16, ("clamped", "free"), 0.1, 1e-3)
    d = _settled(rod)
    static = RodParameters(length=1.0, A=(5.0, 5.0, 5.0), B=(1e4, 1e4, 1e4), density=0.0)
    path, _ = _rod(static, 16, ("clamped", "free"), 0.1, 1e-3, history=lambda t: t)
    path.set_initial_state()
    TimeStepper(path.problem).run(0.0, 1.0, 0.05)
    ref = path.diagnostics(1.0)
    assert -d["tip_position_x"] > 0.09                 # reached the plane 0.1 m below
    for key in ("tip_position_x", "tip_position_z"):
        assert d[key] == pytest.approx(ref[key], abs=1e-11)
    assert d["contact_force_x"] == pytest.approx(ref["contact_force_x"], rel=1e-8)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_free_rod_settles_lying_on_a_plane_below_it(rotations):
    """A free rod (8 cells, rho_A = 1, EI = 1e-2) 50 mm above a plane, its weight towards
    it: no end holds it (allowed with obstacles); settled, it lies flat on the plane, every
    node at the gap where the barrier carries its share of the weight, carrying_gap(rho_A
    g / kappa) (the trapezoidal rule gives the end nodes half the load and half the
    barrier: the same gap), the plane's force the weight, the rod not moved along it
    (nothing pushes it: the tether holds its slides and its turn about its axis).
    Measured: gaps to 4e-15 m, force 1.2e-13 N, slide 2e-14 m; asserted 1e-12 m (1e-9 of
    delta), 1e-9 N and 1e-12 m."""
    params = RodParameters(length=1.0, A=(1e-2, 1e-2, 1e-2), B=(10.0, 10.0, 10.0),
                           density=1.0, section_inertia=1e-5)
    rod, kappa = _rod(params, 8, ("free", "free"), 0.05, 1e-3, rotations=rotations)
    d = _settled(rod)
    assert d["contact_force_x"] == pytest.approx(G, abs=1e-9)
    x = rod.unknowns.f["displacement"]
    owned = x.function_space.dofmap.index_map.size_local
    u = x.x.array.reshape(-1, 3)[:owned]
    comm = MPI.COMM_WORLD
    low = comm.allreduce(float(np.min(u[:, 0], initial=np.inf)), op=MPI.MIN) + 0.05
    high = comm.allreduce(float(np.max(u[:, 0], initial=-np.inf)), op=MPI.MAX) + 0.05
    gap = float(carrying_gap(G / kappa, 1e-3))
    assert low == pytest.approx(gap, abs=1e-12) and high == pytest.approx(gap, abs=1e-12)
    slide = comm.allreduce(float(np.max(np.abs(u[:, 1:]), initial=0.0)), op=MPI.MAX)
    assert slide < 1e-12


SLOPE = (FALLING.replace("n_cells = 4", "n_cells = 8")
         .replace("gravity = [-9.81, 0.0, 0.0]", "gravity = [-8.5, 0.0, -4.9]")
         + '[contact]\nradius = 0.01\n[[obstacles]]\nshape = "plane"\n'
           'point = [-0.06, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\n'
           '[initial]\nequilibrium = true\n')


def test_free_rod_on_a_frictionless_slope_is_refused_naming_initial_equilibrium():
    """A free rod above a frictionless plane with gravity 30 degrees off its normal has
    no static equilibrium (it slides off: friction exerts no force in a static settle):
    the scene is refused naming initial.equilibrium and saying so (without obstacles a
    free rod is refused before any model: EQUILIBRIUM_NEEDS)."""
    from dolfin_rod.scenes import build
    with pytest.raises(SceneError, match=r"\[initial\.equilibrium\]: no static equilibrium"
                                         r".*slides off"):
        build(parse_scene(SLOPE), "rod")
    no_plane = SLOPE[:SLOPE.index("[contact]")] + "[initial]\nequilibrium = true\n"
    with pytest.raises(SceneError, match=r"initial\.equilibrium.*obstacles to rest on"):
        parse_scene(no_plane)
