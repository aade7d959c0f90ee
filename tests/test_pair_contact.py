"""Contact between segments: of one rod (self-contact) and of different rods (issue 26,
rod/pair_contact.py, docs/contact.md).

References: Taylor tests of the pair energy's gradient and Hessian (remainders of first
and second order: ratios 2 and 4 per halving) and of the assembled residual and
Jacobian of a rod system in contact (ratio 4); a cantilever propped by a crossing rod
takes the prop force that linear superposition of two contact-free runs of the same
discretisation gives for the measured deflection at the prop (R = (w_P(a) - w(a)) / f(a),
w_P the deflection under the tip load alone, f the flexibility at a); the pairs' forces
are equal and opposite (the total vanishes).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from dolfin_rod import TimeStepper
from dolfin_rod.rod import EndLoad, RodModel, RodParameters
from dolfin_rod.rod.contact import ContactLaw, barrier_derivatives
from dolfin_rod.rod.pair_contact import exclusion, pair_energy
from dolfin_rod.rod.segments import closest_points
from dolfin_rod.rod.rods import Rod
from dolfin_rod.rod.system import RodSystem

R, DELTA, EI, P, L, N = 0.01, 2e-3, 1.0, 0.05, 1.0, 8
BEAM = RodParameters(length=L, A=(EI, EI, EI), B=(1e4, 1e4, 1e4))
PROP = RodParameters(length=0.5, A=(1e3,) * 3, B=(1e6,) * 3)

CONFIGURATIONS = {   # (p0, p1, q0, q1), centre lines nearer than 2 r + delta = 0.25 below
    "crossing": [[-1, 0, 0], [1, 0, 0], [0.1, -1, 0.235], [0.2, 1, 0.23]],
    "end on segment": [[0, 0, 0], [1, 0, 0], [1.2, -1, 0.1], [0.9, 1, 0.12]],
    "end on end": [[0, 0, 0], [1, 0, 0], [1.1, 0.2, 0.1], [1.5, 0.9, 0.12]],
    "near parallel": [[0, 0, 0], [1, 0, 0], [0.3, 0.05, 0.22], [1.4, -0.02, 0.21]],
}


def _remainders(f, X, dX, steps=5):
    """Ratios of successive first- and second-order Taylor remainders of (E, G) = f(X)."""
    E0, G0, H0 = f(X)
    out = []
    for k in range(steps):
        e = 1e-4 / 2**k
        E1, G1, _ = f(X + e * dX)
        out.append((abs(E1 - E0 - e * G0 @ dX.ravel()).item(),
                    np.linalg.norm(G1 - G0 - e * H0 @ dX.ravel())))
    return np.array(out[:-1]) / np.array(out[1:])


@pytest.mark.parametrize("name", sorted(CONFIGURATIONS))
def test_pair_energy_gradient_and_hessian_are_consistent(name):
    """Energy, gradient and Hessian of a pair (r = 0.1, delta = 0.05: in the barrier's
    range) for crossing, end-on-segment, end-on-end and nearly parallel segments: the
    Taylor remainders fall 4x per halving of the step (exact derivatives; a wrong
    Hessian gives 2x).  Tolerance 0.05: the next order's share at e = 1e-4."""
    X = np.array(CONFIGURATIONS[name], float)[None]
    dX = np.random.default_rng(7).standard_normal(X.shape)

    def f(Y):
        E, G, H = pair_energy(Y, 0.1, 0.05, 1.0, [1.0])
        return E[0], G[0], H[0]
    assert f(X)[0] > 0                      # inside the barrier's range
    ratios = _remainders(f, X, dX)
    assert np.allclose(ratios, 4.0, atol=0.05), ratios


def test_barrier_derivatives():
    """b' and b'' of the barrier against central differences of b (1e-6 relative: the
    differences' truncation error at step 1e-6 delta), b = -(g - delta)^2 ln(g / delta)
    inside, 0 beyond delta, continued below 1e-4 delta by a C^2 polynomial."""
    delta, e = 0.1, 1e-7
    g = np.array([2e-6, 9e-6, 1e-3, 0.03, 0.07, 0.0999, 0.15])
    b, b1, b2 = barrier_derivatives(g, delta)
    inside = (g >= 1e-4 * delta) & (g < delta)
    assert np.allclose(b[inside], -(g[inside] - delta) ** 2 * np.log(g[inside] / delta))
    assert b[-1] == b1[-1] == b2[-1] == 0.0
    plus, minus = barrier_derivatives(g + e, delta), barrier_derivatives(g - e, delta)
    assert np.allclose(b1, (plus[0] - minus[0]) / (2 * e), rtol=1e-6, atol=1e-12)
    assert np.allclose(b2, (plus[1] - minus[1]) / (2 * e), rtol=1e-6, atol=1e-9)


def _propped(a, y0, between=True):
    """Rod A along e_1 (clamped at 0, tip load -P e_3 ramped over t in [0, 1]) over the
    stiff clamped-clamped rod B along e_2 at x = a, from y = y0, its centre line
    2 r + 1.5 delta below A's."""
    rods = [Rod(BEAM, N, "clamped", [EndLoad("force", (0, 0, -P), lambda t: t)],
                orientation=(0, np.pi / 2, 0), name="A"),
            Rod(PROP, 4, "clamped", end="clamped", position=(a, y0, -(2 * R + 1.5 * DELTA)),
                orientation=(-np.pi / 2, 0, 0), name="B")]
    system = RodSystem(rods, model="hyperelastic",
                       contact=ContactLaw(R, DELTA, 1e6, between_rods=between))
    system.set_initial_state()
    return system


def _loaded(model, steps=4):
    stepper = TimeStepper(model.problem)
    for k in range(steps):
        stepper.run(k / steps, (k + 1) / steps, 1 / steps)
    return stepper, model.diagnostics(1.0)


def _node(model, s, k=0):
    """Position of the node at parameter s (all ranks)."""
    x = model.unknowns.f["displacement"]
    n = x.function_space.dofmap.index_map.size_local
    coords = x.function_space.tabulate_dof_coordinates()[:n, 0]
    here = np.isclose(coords, s)
    value = x.x.array.reshape(-1, 3)[:n][here].sum(axis=0) + np.array([0, 0, s]) * here.any()
    return MPI.COMM_WORLD.allreduce(value)


@pytest.mark.mpi
def test_cantilever_propped_by_a_crossing_rod():
    """A (8 cells, EI = 1, tip load 0.05) rests at its node a = 0.75 on B: the contact
    force sum_pairs |f| equals (w_P(a) - w(a)) / f(a) of the same discretisation (two
    contact-free quasi-static runs: A under the tip load, and a rod of length a with 6
    cells, A's first six, under the tip load P) to 1e-3 (the deflections are 2e-3 of L:
    geometric nonlinearity ~1e-5, the barrier's tilt 3e-3 puts an axial force on A,
    which does not bend it); 1.5 P is the rigid prop's beam-theory value, approached
    within 10 %; no pair ever at gap <= 0, the pairs' forces sum to zero."""
    a = 0.75
    system = _propped(a, -0.25)
    _, d = _loaded(system)
    assert 0.0 < d["min_pair_gap"] < DELTA
    w = -_node(system, a)[2]            # A's centre line at s = a (rod A: s in [0, L])
    free = RodModel(BEAM, N, model="hyperelastic",
                    end_loads=[EndLoad("force", (P, 0, 0), lambda t: t)])
    free.set_initial_state()
    _loaded(free)
    w_P = _node(free, a)[0]
    short = RodModel(RodParameters(**{**BEAM.__dict__, "length": a}), 6,
                     model="hyperelastic", end_loads=[EndLoad("force", (P, 0, 0))])
    short.set_initial_state()
    _loaded(short, 1)
    flexibility = _node(short, a)[0] / P
    assert d["pair_contact_force"] == pytest.approx((w_P - w) / flexibility, rel=1e-3)
    assert d["pair_contact_force"] == pytest.approx(1.5 * P, rel=0.1)
    forces = system.segment_contact.force_density()
    total = MPI.COMM_WORLD.allreduce((forces * (L / N)).sum(axis=0))
    assert np.linalg.norm(total) < 1e-12 * d["pair_contact_force"] + 1e-15


@pytest.mark.mpi
def test_assembled_jacobian_is_consistent():
    """The step's residual and Jacobian of the propped system in contact at interior
    points of both segments (B's nodes and A's off the crossing): Taylor remainders of
    the residual fall 4x per halving (forms and pair terms exact; tolerance 0.1: the
    remainder's next order at e = 1e-6 of a state of size 1)."""
    system = _propped(0.75 + L / N / 3, -0.3)
    stepper, d = _loaded(system)
    assert d["contact_pairs"] >= 1 and d["min_pair_gap"] < DELTA
    sys_ = stepper.integrator.solver.system
    x = sys_.x.copy()
    b0, b1 = x.duplicate(), x.duplicate()
    sys_.set(0, x)
    sys_.residual(x, b0)
    sys_.jacobian(sys_.A)
    dx = x.duplicate()
    dx.setArray(np.random.default_rng(3 + MPI.COMM_WORLD.rank).standard_normal(
        x.getLocalSize()))
    dx.array_w[sys_.bc_rows] = 0.0
    Adx = x.duplicate()
    sys_.A.mult(dx, Adx)
    rem = []
    for k in range(4):
        e = 1e-6 / 2**k
        y = x.copy()
        y.axpy(e, dx)
        sys_.set(0, y)
        sys_.residual(y, b1)
        b1.axpy(-1.0, b0)
        b1.axpy(-e, Adx)
        rem.append(b1.norm())
    ratios = np.array(rem[:-1]) / np.array(rem[1:])
    assert np.allclose(ratios, 4.0, atol=0.1), ratios


@pytest.mark.mpi
def test_contact_off_changes_nothing():
    """between_rods = False: no term in the problem, the run equals the same system
    without a contact law bit for bit (A then falls through B's place)."""
    off = _propped(0.75, -0.25, between=False)
    assert not off.problem.terms
    rods = [Rod(BEAM, N, "clamped", [EndLoad("force", (0, 0, -P), lambda t: t)],
                orientation=(0, np.pi / 2, 0), name="A"),
            Rod(PROP, 4, "clamped", end="clamped", position=(0.75, -0.25, -(2 * R + 1.5 * DELTA)),
                orientation=(-np.pi / 2, 0, 0), name="B")]
    plain = RodSystem(rods, model="hyperelastic")
    plain.set_initial_state()
    _loaded(off)
    _loaded(plain)
    assert np.array_equal(off.unknowns.f["displacement"].x.array,
                          plain.unknowns.f["displacement"].x.array)


def test_neighbour_exclusion_and_bad_radius():
    """Neighbours closer along the rod than pi (r + delta) + h are no pair; a radius
    whose exclusion covers the whole rod is refused naming contact.radius."""
    assert exclusion(0.01, 0.001, 0.1) == pytest.approx(np.pi * 0.011 + 0.1)
    with pytest.raises(ValueError, match="contact.radius"):
        RodModel(BEAM, N, model="hyperelastic",
                 contact=ContactLaw(0.3, 0.03, 1.0, self=True))


def _ring_drift(dt, t_end=0.5):
    """A free rod whose stress-free shape is 0.95 of a circle (L = 1, r = 0.01), its ends
    sent towards each other at 0.1 m/s: they meet (self-contact), bounce and the ring
    rings; frictionless, no drag, generalized-alpha with rho_inf = 1 (no numerical
    dissipation).  Returns (largest |E(t) - E(0)| of E = K + Psi + contact energy, largest
    contact energy, smallest pair gap)."""
    from dolfin_rod.rod.start import StartingState
    kappa = 2 * np.pi * 0.95
    params = RodParameters(length=1.0, A=(1e-2,) * 3, B=(10.0,) * 3, density=0.1,
                           section_inertia=1e-6, reference_curvature=(kappa, 0, 0))
    rod = RodModel(params, 40, model="hyperelastic", start="free", end="free",
                   contact=ContactLaw(0.01, 0.002, 1e3, self=True))
    ends, _ = rod.stress_free(np.array([0.0, 1.0]))
    chord = (ends[0] - ends[1]) / np.linalg.norm(ends[0] - ends[1])
    rod.set_initial_state(start=StartingState(
        velocity=lambda s: 0.1 * (2 * np.asarray(s) - 1)[:, None] * chord))
    drift, _, contact, gap = energy_drift(rod, dt, t_end, "min_pair_gap")
    return drift, contact, gap


def energy_drift(rod, dt: float, t_end: float, gap: str) -> tuple:
    """``rod`` stepped to t_end by generalized-alpha with rho_inf = 1 (no numerical
    dissipation): (largest |E(t) - E(0)| of E = K + Psi + contact energy, E(0), largest
    contact energy, smallest diagnostics[gap])."""
    stepper = TimeStepper(rod.problem, "generalized_alpha:1.0",
                          {"snes_rtol": 1e-10, "snes_atol": 1e-12})
    energy, contact, smallest = [], 0.0, np.inf
    for k in range(int(round(t_end / dt)) + 1):
        if k:
            stepper.run((k - 1) * dt, k * dt, dt)
        d = rod.diagnostics(k * dt)
        energy.append(d["kinetic_energy"] + d["free_energy"] + d["contact_energy"])
        contact, smallest = max(contact, d["contact_energy"]), min(smallest, d[gap])
    return np.max(np.abs(np.array(energy) - energy[0])), energy[0], contact, smallest


# Serial only: the same ring's self-contact on two ranks is test_pair_friction.py's
# test_self_friction_dissipates_and_the_power_balance_closes (this ring with friction,
# its power balance at second order) and test_zero_friction_is_the_frictionless_contact.
def test_frictionless_contact_conserves_energy_at_second_order():
    """The ring's ends collide (the barrier's energy reaches 3.5 % of E, the gap 0.64
    delta) and K + Psi + contact energy is conserved to the integrator's
    order: the largest drift over 0.5 s falls 4x per halving of dt (measured 4.57,
    4.47, 4.19 from dt = 4e-3 to 5e-4; 4.8e-7 of E = 1.7e-4 at dt = 4e-3).  Asserted:
    ratios > 3.5.  (A harder impact, 0.3 m/s onto kappa = 100, is not resolved by
    these steps: the energy then wanders by 10-50 %, docs/contact.md.)"""
    runs = [_ring_drift(dt) for dt in (4e-3, 2e-3, 1e-3)]
    drifts = np.array([r[0] for r in runs])
    assert all(r[1] > 1e-6 and r[2] < 0.7 * 0.002 for r in runs), runs
    assert np.all(drifts[:-1] / drifts[1:] > 3.5), drifts


def _coiled_rod(n_cells=120):
    """A rod (r = 1 cm, h = 1 cm) wound into a helix whose coils are 2 r + delta / 2
    apart: every segment within the barrier's reach of the coils next to it."""
    params = RodParameters(length=n_cells * R, A=(1.0,) * 3, B=(1e3,) * 3, density=1.0,
                           section_inertia=1e-4)
    model = RodModel(params, n_cells, model="hyperelastic", start="free", end="free",
                     contact=ContactLaw(R, DELTA, 1e3, self=True))
    model.set_initial_state()
    x = model.unknowns.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    radius, pitch = 0.05, 2 * R + DELTA / 2
    phi = s / np.hypot(radius, pitch / (2 * np.pi))
    helix = np.stack([radius * np.cos(phi), radius * np.sin(phi), pitch * phi / (2 * np.pi)])
    x.x.array[:] = (helix.T - np.outer(s, (0, 0, 1))).ravel()
    return model


@pytest.mark.mpi
def test_update_check_keeps_a_margin_below_the_barriers_taylor_range():
    """Newton's update check (``step_fraction``: the largest 2^-k of an update along
    which no pair's gap g falls below 0.1 g0, or by more than 0.9 g_min where g0 < g_min
    = 1e-4 delta).  Rods A and B crossing inside a segment of each at g0 = 1e-3 g_min:
    B moved 2 g_min towards A is cut to 0.25 (0.25 x 2 g_min <= 0.9 g_min < 0.5 x 2
    g_min; with the floor 0.1 g0 alone 2^-12, found by ~2^20 bisections of the path per
    pair, docs/contact.md "Cost of the crossing"); B sliding 1e-4 m along itself keeps
    the gap (crossing lines) and is not cut; at g0 = 0.5 delta the floor is 0.1 g0: an
    approach by g0 is cut to 0.5 (0.9 g0 / g0 = 0.9)."""
    contact = _propped(0.8125, -0.3125).segment_contact     # crossing inside segments
    line = contact.line
    P = line.positions(contact.owned_displacement())
    b = np.unique(line.ends[line.rod == 1])
    g_min = 1e-4 * DELTA
    for g0, approach, expected in ((1e-3 * g_min, 2 * g_min, 0.25), (0.5 * DELTA, 0.5 * DELTA,
                                                                       0.5)):
        P0 = P.copy()
        P0[b, 2] += 1.5 * DELTA - g0                         # B's gap to A: g0
        up, slide = P0.copy(), P0.copy()
        up[b, 2] += approach
        slide[b, 1] += 1e-4
        assert contact.step_fraction(P0, up) == expected
        assert contact.step_fraction(P0, slide) == 1.0


@pytest.mark.mpi
def test_candidate_list_finds_every_pair_within_reach():
    """The pairs of the candidate list (kept while the nodes move less than half the
    skin, else searched anew) are the pairs a search over all segment pairs finds
    (closest points of every pair i < j farther apart in s than the exclusion), in the
    same order, after moves of 0.2, 0.45 and 2 skins' worth of random noise (list kept,
    kept, searched anew).  Exact: the same closest-point arithmetic decides both."""
    contact = _coiled_rod().segment_contact
    line = contact.line
    P0 = line.positions(contact.owned_displacement())
    i, j = np.triu_indices(len(line.ends), 1)
    far = np.abs(line.mid_s[i] - line.mid_s[j]) >= contact.exclusion
    i, j = i[far], j[far]
    rng = np.random.default_rng(5)
    contact.pairs(P0)
    for share in (0.2, 0.45, 2.0):
        move = rng.uniform(-1, 1, P0.shape)
        P = P0 + share * contact.skin * move / np.linalg.norm(move, axis=1).max()
        X = P[line.ends[np.stack([i, j], 1)].reshape(-1, 4)]
        near = closest_points(X[:, 0], X[:, 1], X[:, 2], X[:, 3])[2] < contact.reach
        found = contact.pairs(P)
        assert len(found) > len(line.ends)          # the coils touch all along
        assert np.array_equal(found, np.stack([i[near], j[near]], 1))


@pytest.mark.mpi
def test_pair_terms_reuse_the_searchs_closest_points_bit_for_bit():
    """The pairs' terms take the closest points the pair search computed (``near``)
    instead of computing them again: the same bits as pair_energy computing its own
    (elementwise arithmetic on a superset then filtered), on the coiled rod (3 pairs
    per segment) at its state and after a random move."""
    contact = _coiled_rod().segment_contact
    line = contact.line
    P0 = line.positions(contact.owned_displacement())
    for P in (P0, P0 + 0.3 * contact.skin * np.random.default_rng(2).uniform(-1, 1, P0.shape)):
        pairs, closest = contact.near(P)
        X = P[line.ends[pairs].reshape(-1, 4)]
        weights = 0.5 * line.lengths[pairs].sum(axis=1)
        law = contact.law
        mine = pair_energy(X, law.radius, law.gap, law.stiffness, weights, closest=closest)
        own = pair_energy(X, law.radius, law.gap, law.stiffness, weights)
        assert len(pairs) > len(line.ends)
        assert all(np.array_equal(a, b) for a, b in zip(mine, own))
    terms = contact.evaluate(contact.owned_displacement())      # the path a solve takes
    X = P0[line.ends[terms.pairs].reshape(-1, 4)]
    own = pair_energy(X, law.radius, law.gap, law.stiffness,
                      0.5 * line.lengths[terms.pairs].sum(axis=1))
    assert all(np.array_equal(a, b) for a, b in zip(terms[2:], own))


@pytest.mark.mpi
def test_jacobian_pattern_grows_once_and_keeps_the_forms_entries():
    """The coiled rod's step Jacobian: the first assembly adds the pairs' entries to the
    matrix pattern (fem/assembly.grow_pattern, which copies the forms' assembled values
    into the grown matrix) and equals the reference: the forms' Jacobian assembled into
    a matrix of that pattern and the pairs' Hessians added (to 1e-14: the same sums in
    another order); the next Jacobian at the same pairs needs no new entry (pattern
    unchanged, no allocation)."""
    model = _coiled_rod()
    system = TimeStepper(model.problem).solver.system
    x, b = system.x, system.b.duplicate()
    system.get(0, x)
    system.residual(x, b)
    system.jacobian(system.A)
    assert system.pattern_changes == 1
    reference = system.A.duplicate(copy=False)
    terms, system.terms = system.terms, ()
    system.jacobian(reference)                          # the forms only
    system.terms = terms
    reference.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    terms[0].add_jacobian(reference)
    reference.assemble()
    reference.axpy(-1.0, system.A, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
    assert reference.norm() <= 1e-14 * system.A.norm()
    model.segment_contact.forget()
    system.residual(x, b)
    system.jacobian(system.A)
    assert system.pattern_changes == 1
    assert system.A.getInfo()["mallocs"] == 0


# -- bad input at t = 0, as a user runs it (dolfin-rod check | run) --------------------------

HAIRPIN = """
[material]
model = "hyperelastic"
stiffness = { A = [1e-2, 1e-2, 1e-2], B = [10.0, 10.0, 10.0] }
[geometry]
n_cells = 40
[boundary]
start = "clamped"
end = "free"
[initial]
shape = { type = "polyline", points = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.5], [0.015, 0.0, 0.5], [0.015, 0.0, 0.015]] }
[contact]
radius = 0.01
self = true
[time]
t_end = 0.1
dt = 0.1
"""


def _checked(tmp_path, text: str, command: str = "check"):
    from test_cli import cli
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return cli(command, path, *(("--out", tmp_path / "run", "--quiet") if command == "run"
                                else ()))


@pytest.mark.parametrize("scene, key, says", [
    # a hairpin (L = 1): legs 0.015 apart, capsules of r = 0.01 overlap by 2 r - 0.015
    (HAIRPIN, "contact.self", "overlap by 0.005 at t = 0 (their centre lines are closer "
                              "than 2 contact.radius = 0.02)"),
    # crossing_rods.toml with the prop 8 mm below the beam (r = 5 mm): overlap 2 mm where
    # they cross, at x = 0.75 on the beam (a node: its first segment, s in [0.625, 0.75]),
    # y = 0 on the prop (s = 0.25, a node: segment [0.125, 0.25])
    ("crossing_rods", "contact.between_rods",
     "segments of rod beam at s = 0.6875 and rod prop at s = 0.1875, near (0.75, 0, "
     "-0.004): overlap by 0.002 at t = 0"),
    # self-contact whose neighbour exclusion pi (r + delta) + h = pi (0.35 + 0.035) + 1/40
    # = 1.2345 (delta = r / 10 by default) covers the rod (L = 1)
    (HAIRPIN.replace("radius = 0.01", "radius = 0.35"), "contact.radius",
     "self-contact excludes neighbours closer along the rod than pi (r + delta) + h = "
     "1.235, which is not shorter than the rod (1)"),
])
def test_check_refuses_segments_overlapping_at_the_start(tmp_path, scene, key, says):
    """``dolfin-rod check`` exits 2 with one line naming the key, before any model (was:
    OK; ``run`` then failed with a traceback, exit 1, for the overlaps, and named
    scene.model for the radius); the same scenes started apart pass."""
    from pathlib import Path
    if scene == "crossing_rods":
        scene = (Path(__file__).parents[1] / "scenes" / "crossing_rods.toml").read_text()
        apart = scene
        scene = scene.replace("position = [0.75, -0.25, -0.01075]",
                              "position = [0.75, -0.25, -0.008]")
    else:
        apart = scene.replace("[0.015, 0.0, 0.5], [0.015, 0.0, 0.015]",
                              "[0.025, 0.0, 0.5], [0.025, 0.0, 0.025]").replace(
            "radius = 0.35", "radius = 0.01")
    proc = _checked(tmp_path, scene)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.count("\n") == 1 and f"[{key}]" in proc.stderr and says in proc.stderr
    assert _checked(tmp_path, apart).returncode == 0


def test_check_says_how_segments_touch(tmp_path):
    """``dolfin-rod check`` prints a contact line for self-contact and for contact
    between rods, as it does for obstacles: the exclusion pi (r + delta) + h with
    r = 0.01, delta = r / 10 (the default), h = 1/40."""
    proc = _checked(tmp_path, HAIRPIN.replace("[0.015, 0.0, 0.5], [0.015, 0.0, 0.015]",
                                              "[0.025, 0.0, 0.5], [0.025, 0.0, 0.025]"))
    assert proc.returncode == 0, proc.stderr
    assert ("contact: self (the rod's own segments, capsules of radius 0.01, barrier gap "
            "0.001, pair_curve = 'segments', frictionless) excludes neighbours closer along "
            f"the rod than pi (r + gap) + h = {np.pi * 0.011 + 1 / 40:.4g} (longest cell "
            "h = 0.025)") in proc.stdout
    from test_cli import cli
    from pathlib import Path
    crossing = cli("check", Path(__file__).parents[1] / "scenes" / "crossing_rods.toml")
    assert ("contact: between_rods (segments of different rods, capsules of radius 0.005, "
            "barrier gap 0.0005, pair_curve = 'segments', frictionless)") in crossing.stdout


def test_smooth_pairs_overlapping_at_the_start_are_refused(tmp_path):
    """The hairpin with the pairs on smooth curves (contact.pair_curve = "smooth"): its
    straight legs are their own curves, so ``dolfin-rod check`` refuses it with the same
    overlap 0.005, naming contact.self (was: OK, and ``run`` failed with a traceback,
    exit 1); the model's own check at t = 0 (the API) raises the same error."""
    from dolfin_rod.rod.segments import PairOverlap
    from dolfin_rod.rod.start import Polyline, StartingState
    smooth = HAIRPIN.replace("self = true", 'self = true\npair_curve = "smooth"')
    proc = _checked(tmp_path, smooth)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "[contact.self]" in proc.stderr and "overlap by 0.005 at t = 0" in proc.stderr
    params = RodParameters(length=1.0, A=(1e-2,) * 3, B=(10.0,) * 3)
    rod = RodModel(params, 40, model="hyperelastic", start="clamped", end="free",
                   contact=ContactLaw(0.01, 0.001, 1.0, self=True, pair_curve="smooth"))
    with pytest.raises(PairOverlap) as err:
        rod.set_initial_state(start=StartingState(shape=Polyline(
            ((0.0, 0.0, 0.0), (0.0, 0.0, 0.5), (0.015, 0.0, 0.5), (0.015, 0.0, 0.015)))))
    assert err.value.key == "contact.self" and "overlap by 0.005 at t = 0" in str(err.value)
