"""Starting equilibria and quasi-static starts that one Newton solve does not reach
(rod/initial_state.py settle and _settle_in_pseudo_time; integrators/lie_alpha.py
_loaded_in_parts; docs/rod.md, "A start in static equilibrium").

References: the elastica of a cantilever under a dead tip force P (Bisshopp & Drucker
1945, in elliptic integrals: k L = K(p) - F(phi_1, p), p^2 = (1 + sin theta_0)/2, sin phi_1
= 1/(p sqrt 2); tip along the clamp sqrt(2 sin theta_0)/k, across it L - 2 (E(p) -
E(phi_1, p))/k), checked here against Mattiasson's (1981) table; the planar Reissner rod
of the same quadratic energy (extension and shear included) under its own weight,
integrated by scipy to 1e-12 and shot on its clamp moment (a heavy cantilever has no
closed form); a pinned rod hanging under its weight (stretched by q L^2 / (2 EA),
exact for the P1 rod); the same equilibrium reached by an independent path (a
quasi-static rod whose load is ramped from 0 over load steps: the same static
equations); two rods joined rigidly in line are the one rod of their cells.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, newton
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

from dolfin_rod import Rod, RodSystem, TimeStepper
from dolfin_rod.rod import DistributedLoad, EndLoad, RodModel, RodParameters, StartingState
from dolfin_rod.rod.joints import Joint

EI, STIFF = 1.0, 1e7      # bending; shear and axial stiffness (their compliance P / GA
                          # ~ 1e-6 of the tip: negligible against the asserted errors)


def elastica_tip(load: float) -> tuple[float, float, float]:
    """(along the clamp, across it, tip angle) / L of the inextensible cantilever under a
    dead tip force across its clamp, load = P L^2 / EI (Bisshopp & Drucker 1945)."""
    kL = np.sqrt(load)

    def parameter(theta0):
        return (1 + np.sin(theta0)) / 2, np.arcsin(1 / np.sqrt(1 + np.sin(theta0)))

    def length(theta0):
        m, phi1 = parameter(theta0)
        return ellipk(m) - ellipkinc(phi1, m) - kL

    theta0 = brentq(length, 1e-9, np.pi / 2 - 1e-15, xtol=1e-15)
    m, phi1 = parameter(theta0)
    return (np.sqrt(2 * np.sin(theta0)) / kL,
            1 - 2 * (ellipe(m) - ellipeinc(phi1, m)) / kL, theta0)


def test_elastica_closed_form_is_mattiasson_table():
    """The closed form above against Mattiasson's (1981) five digits (his table of the
    tip's horizontal shortening u/L, deflection w/L and angle), and the shot Reissner rod
    (the reference of the tests below) against it where shear and extension vanish."""
    table = {1.0: (0.05643, 0.30172, 0.46135), 2.0: (0.16064, 0.49346, 0.78175),
             5.0: (0.38763, 0.71379, 1.21537), 10.0: (0.55500, 0.81061, 1.43029)}
    for load, (u, w, angle) in table.items():
        along, across, theta0 = elastica_tip(load)
        assert (1 - along, across, theta0) == pytest.approx((u, w, angle), abs=6e-6)
    # the Reissner rod stiff in shear and extension (GA = EA = 1e9) is the elastica but
    # for its shear P L / GA = 1e-8 across (measured 2e-14 along, 1.0e-8 across)
    assert reissner_tip(0.0, 10.0, 1e9, 1e9) == pytest.approx(elastica_tip(10.0)[:2],
                                                             abs=2e-8)


def reissner_tip(q: float, P: float, EA: float, GA: float) -> tuple[float, float]:
    """(along the clamp, across it) of the tip of a clamped planar Reissner rod (L = 1,
    EI = 1, m = EI phi', n = EA (v_3 - 1) d_3 + GA v_1 d_1) under its weight q per length
    and a dead tip force P across the clamp: shot on the clamp moment, the loads raised
    from 0 in 100 steps (each shot from the last: a heavy cantilever has several
    equilibria)."""
    def rhs(s, y, f):
        _, _, phi, m = y
        n = f * (q * (1.0 - s) + P)                 # the shear force, across the clamp
        v3, v1 = 1 + n * np.sin(phi) / EA, n * np.cos(phi) / GA
        along = v3 * np.cos(phi) - v1 * np.sin(phi)
        return [along, v3 * np.sin(phi) + v1 * np.cos(phi), m / EI, -along * n]

    def shot(m0, f):
        return solve_ivp(rhs, (0.0, 1.0), [0.0, 0.0, 0.0, m0], args=(f,), rtol=1e-12,
                         atol=1e-13).y[:, -1]

    m0 = 0.0
    for f in np.linspace(0.0, 1.0, 101)[1:]:
        m0 = newton(lambda m, f=f: shot(m, f)[3], m0, tol=1e-13)
    z, x, *_ = shot(m0, 1.0)
    return z, x


def cantilever(n_cells: int, rotations="auto", weight=0.0, tip=0.0, density=1.0,
               history=lambda t: 1.0, axial=STIFF) -> RodModel:
    """A clamped cantilever along e_3 (L = 1, EI = 1) loaded across it along -e_1: a
    weight per length and a tip force, dynamic (density 1) or quasi-static (0)."""
    params = RodParameters(length=1.0, A=(EI, EI, EI), B=(axial, axial, axial),
                           density=density, section_inertia=1e-3 if density else 0.0)
    return RodModel(params, n_cells=n_cells, model="hyperelastic", rotations=rotations,
                    distributed_loads=[DistributedLoad("force", (-weight, 0, 0), history)]
                    if weight else [],
                    end_loads=[EndLoad("force", (-tip, 0, 0), history)] if tip else [])


def settled(model) -> dict:
    model.set_initial_state(start=StartingState(equilibrium=True))
    return model.diagnostics(0.0)


def quasi_static_path(model, steps: int = 20) -> dict:
    """The equilibrium at t = 1 of a quasi-static model whose loads are ramped by t."""
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, 1.0, 1.0 / steps)
    return model.diagnostics(1.0)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_tip_loaded_elastica_settles_to_the_closed_form(rotations):
    """A cantilever (EA = GA = 1e5) under a dead tip force P L^2 / EI = 10 (tip angle 82
    degrees), started straight in equilibrium: one Newton solve from the straight start
    fails, the settle's pseudo-time finds the elastica.  32 cells: against the planar
    Reissner rod, the elastica's closed form but for the shear P L / GA = 1e-4 across
    (test_elastica_closed_form_is_mattiasson_table): measured 2.75e-4 along, 1.75e-4
    across (with EA = GA = 1e7 against the closed form: 2.75e-4, 1.74e-4; 1.09e-3, 6.9e-4
    at 16 cells: the discretisation's h^2), asserted 4e-4; both rotation unknowns give
    the same state (to 1e-15).  (EA = GA = 1e7 on quaternions: the residual's round-off
    floor on 2 ranks, 1.3e-7 N, is above Newton's tolerance.)"""
    d = settled(cantilever(32, rotations, tip=10.0, axial=1e5))
    along, across = reissner_tip(0.0, 10.0, 1e5, 1e5)
    assert d["tip_position_z"] == pytest.approx(along, abs=4e-4)
    assert -d["tip_position_x"] == pytest.approx(across, abs=4e-4)


@pytest.mark.mpi
def test_heavy_cantilever_settles_as_the_load_path_and_the_reissner_rod():
    """The cantilever of the formerly refused scene (q L^3 / EI = 60, EA = GA = 1e4, tip
    angle 88 degrees; tests/test_start.py's DROOPING), 16 cells, settled from the straight
    start: (a) the equilibrium a quasi-static rod reaches with its weight ramped from 0
    over 20 load steps (the same static equations: tip to 1.2e-12 m measured, asserted
    1e-10 m against Newton's tolerance 1e-10 of the forces); (b) the planar Reissner rod:
    measured 1.9e-3 along, 1.6e-3 across (5.1e-4, 4.3e-4 at 32 cells: h^2), asserted
    2.5e-3; (c) the quasi-static rod under the weight constant in time (all of it on the
    start: one Newton solve fails, the start's load path reaches it) is the same state
    (measured 1.1e-12 m, asserted 1e-10 m)."""
    d = settled(cantilever(16, weight=60.0, axial=1e4))
    ramped = quasi_static_path(cantilever(16, weight=60.0, density=0.0, axial=1e4,
                                          history=lambda t: t))
    for key in ("tip_position_x", "tip_position_z"):
        assert d[key] == pytest.approx(ramped[key], abs=1e-10)
    along, across = reissner_tip(60.0, 0.0, 1e4, 1e4)
    assert d["tip_position_z"] == pytest.approx(along, abs=2.5e-3)
    assert -d["tip_position_x"] == pytest.approx(across, abs=2.5e-3)
    constant = cantilever(16, weight=60.0, density=0.0, axial=1e4)
    constant.set_initial_state()
    TimeStepper(constant.problem).run(0.0, 0.1, 0.1)
    c = constant.diagnostics(0.1)
    for key in ("tip_position_x", "tip_position_z"):
        assert c[key] == pytest.approx(ramped[key], abs=1e-10)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_quasi_static_tip_load_constant_in_time_is_the_elastica(rotations):
    """A quasi-static cantilever (EA = GA = 1e5) under a dead tip force P L^2 / EI = 10
    constant in time: Newton under the whole load fails, where cutting the step would not
    lessen it (it did: IntegrationError "the start at t = 0" with rotation vectors, whose
    generalized-alpha start solves the equilibrium at t0; "time step failed at t = 0
    after 6 step cuts" with quaternions' BDF2).  The start's (lie_alpha._loaded_in_parts)
    or the first step's (stepper.SchemeStepper._on_load_path) load path reaches the
    elastica, and the next step keeps it.  32 cells, against the planar Reissner rod
    (its shear P L / GA = 1e-4 across; the inextensible closed form is checked in the
    settled test above): measured 2.75e-4 along, 1.75e-4 across, both rotation unknowns
    (the same state to 1e-16), asserted 4e-4 (h^2, as the settled test's)."""
    model = cantilever(32, rotations, tip=10.0, density=0.0, axial=1e5)
    model.set_initial_state()
    # Newton's absolute tolerance 1e-8 N: the residual's round-off floor at this state is
    # 1.2e-9 N on 2 ranks (MUMPS, rotation vectors: the step after the start failed at
    # the default 1e-10, "CONVERGED_SNORM_RELATIVE but the residual norm ... 1.21e-09");
    # 1e-8 N moves the tip by ~1e-8 m against the 4e-4 asserted
    TimeStepper(model.problem, solver_options={"snes_atol": 1e-8}).run(0.0, 0.2, 0.1)
    d = model.diagnostics(0.2)
    along, across = reissner_tip(0.0, 10.0, 1e5, 1e5)
    assert d["tip_position_z"] == pytest.approx(along, abs=4e-4)
    assert -d["tip_position_x"] == pytest.approx(across, abs=4e-4)


@pytest.mark.mpi
def test_rods_joined_in_line_settle_as_the_one_rod():
    """Two cantilever halves (8 cells each) joined rigidly in line, the tip force P L^2 /
    EI = 10 on the second: settled (one solve fails; the pseudo-time carries the joint's
    links) it is the one rod of 16 cells (the same equations: measured 1.9e-14 m, asserted
    1e-10 m, Newton's tolerance)."""
    params = RodParameters(length=0.5, A=(EI, EI, EI), B=(STIFF, STIFF, STIFF),
                           density=1.0, section_inertia=1e-3)
    system = RodSystem([Rod(params, 8, name="a"),
                        Rod(params, 8, "free", position=(0.0, 0.0, 0.5), name="b",
                            end_loads=[EndLoad("force", (-10.0, 0.0, 0.0))])],
                       joints=[Joint("rigid", ("a", "b"), (0.0, 0.0, 0.5))],
                       model="hyperelastic")
    system.set_initial_state(start={"a": StartingState(equilibrium=True)})
    d = system.diagnostics(0.0)
    one = settled(cantilever(16, tip=10.0))
    for c in "xz":
        assert d[f"b.tip_position_{c}"] == pytest.approx(one[f"tip_position_{c}"], abs=1e-10)


@pytest.mark.mpi
def test_pinned_rod_settles_hanging_under_its_weight():
    """A rod pinned at s = 0, started straight across its weight (a pinned end holds no
    rotation: no single Newton solve from there), settles hanging straight down,
    stretched by its weight: tip at L + q L^2 / (2 EA) below the pin (exact for the P1
    rod: the cell forces are the weight below each cell's midpoint; measured 4.8e-13 m,
    asserted 1e-10 m), no sideways offset: measured 1.9e-10 m, asserted 1e-9 m (the
    settle stops at a rest force below Newton's tolerance, 1e-10 of the force scale q L =
    2 N, against the hanging rod's sideways stiffness at its tip, about q L / L = 2 N/m)."""
    q, EA = 2.0, 50.0
    params = RodParameters(length=1.0, A=(0.1, 0.1, 0.1), B=(EA, EA, EA), density=1.0,
                           section_inertia=1e-3)
    model = RodModel(params, n_cells=8, start="pinned", model="hyperelastic",
                     distributed_loads=[DistributedLoad("force", (-q, 0.0, 0.0))])
    d = settled(model)
    assert d["tip_position_x"] == pytest.approx(-(1.0 + q / (2 * EA)), abs=1e-10)
    assert abs(d["tip_position_y"]) < 1e-9 and abs(d["tip_position_z"]) < 1e-9
