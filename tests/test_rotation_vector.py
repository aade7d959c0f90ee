"""The dynamic rod's default rotation unknowns: an incremental rotation vector on stored
nodal unit quaternions (6 unknowns per node, rod/rotation_vector.py), and its Lie-group
generalized-alpha (integrators/lie_alpha.py).

References: RodModel's strains for the same nodal unit quaternions (the verified
quaternion + gauge discretisation: both interpolate the nodal quaternions linearly and
evaluate the strains at the cell midpoint, so they must agree to round-off); exact
invariance under a superposed rigid rotation; a closed loop of nodal rotations whose
product is the identity returns the strains to round-off; the observed order of the time
integrator against a run with a 16x smaller step.
"""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod.fem import form_cache
from dolfin_rod import loads
from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, EndLoad, RodModel, RodParameters
from dolfin_rod.rod.rotation_vector import np_cayley
from dolfin_rod.theory.rotations import np_qmul, np_quaternion_from_rotation_vector, np_rotation_matrix

TIGHT = {"snes_lag_jacobian": 1, "snes_lag_preconditioner": 1, "snes_rtol": 1e-10}
PARAMS = RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2), density=2.0,
                       section_inertia=1e-3)


def _nodal(rod, fn, width):
    """Nodal values fn(s) (rows) on the P1 dofs of a field with ``width`` components."""
    V = rod.f["displacement"].function_space
    s = V.tabulate_dof_coordinates()[:, 0]
    return np.array([fn(si) for si in s]).reshape(-1, width)


def _strains(rod):
    """(u, v) at the cell midpoints, (n_cells, 6)."""
    return np.hstack([rod.pointwise(rod.u), rod.pointwise(rod.v)])


def _rod(params=PARAMS, n_cells=6, **kwargs):
    rod = RodModel(params, n_cells=n_cells, model="hyperelastic", **kwargs)
    assert rod.rotations == "rotation_vector"     # the default of a dynamic rod
    return rod


def _deformed(rod):
    """A large, smooth deformation: nodal unit quaternions, displacements, increments."""
    rod.set_initial_state()
    phi = _nodal(rod, lambda s: (1.3 * np.sin(3 * s), 2.0 * s * np.cos(2 * s), 1.5 * s**2), 3)
    rod.unknowns.chart.set_nodal_rotations(np_quaternion_from_rotation_vector(phi))
    rod.f["displacement"].x.array[:] = _nodal(
        rod, lambda s: (0.3 * s**2, -0.2 * np.sin(s), 0.1 * s), 3).ravel()
    rod.f["rotation_increment"].x.array[:] = _nodal(
        rod, lambda s: (0.4 * np.cos(5 * s), 0.3 * s, -0.5 * s**3), 3).ravel()


@pytest.mark.mpi
def test_strains_equal_rodmodel_strains():
    rod = _rod()
    _deformed(rod)
    th = rod.f["rotation_increment"].x.array.reshape(-1, 3)
    q_nodes = np_qmul(rod.unknowns.chart.q_n.x.array.reshape(-1, 4), np_cayley(th))
    ref = RodModel(PARAMS, n_cells=6, model="hyperelastic", rotations="quaternion")
    ref.set_initial_state()
    ref.f["quaternion"].x.array[:] = q_nodes.ravel()
    ref.f["displacement"].x.array[:] = rod.f["displacement"].x.array
    expected = _strains(ref)
    # same formula on the same nodal values: round-off of O(10) operations on O(1) data
    assert np.allclose(_strains(rod), expected, rtol=0, atol=1e-13 * np.abs(expected).max())


@pytest.mark.mpi
def test_superposed_rigid_rotation_leaves_strains():
    rod = _rod()
    _deformed(rod)
    before = _strains(rod)
    qQ = np_quaternion_from_rotation_vector(np.array([0.7, -2.1, 1.2]))
    RQ = np_rotation_matrix(qQ)
    chart = rod.unknowns.chart
    chart.set_nodal_rotations(np_qmul(qQ, chart.q_n.x.array.reshape(-1, 4)))
    x = rod.f["displacement"].x.array.reshape(-1, 3)
    X = np.outer(rod.f["displacement"].function_space.tabulate_dof_coordinates()[:, 0],
                 [0, 0, 1.0])
    x[:] = (X + x) @ RQ.T - X
    # exact invariance (q -> q_Q q is linear); round-off of a few products of O(1) data
    assert np.allclose(_strains(rod), before, rtol=0, atol=1e-13 * np.abs(before).max())


@pytest.mark.mpi
def test_closed_loop_of_rotations_returns_strains():
    rod = _rod()
    _deformed(rod)
    chart = rod.unknowns.chart
    rod.f["rotation_increment"].x.array[:] = 0.0
    start, q_start = _strains(rod), chart.q_n.x.array.copy()
    th = rod.f["rotation_increment"].x.array.reshape(-1, 3)
    steps = [lambda s: (0.9 * s, 0.2, -0.4), lambda s: (-0.3, 1.1 * s**2, 0.5 * s),
             lambda s: (0.6, -0.7, 0.8 * np.cos(s))]
    product = np.tile([1.0, 0, 0, 0], (th.shape[0], 1))
    for fn in steps:
        inc = _nodal(rod, fn, 3)
        th[:] = inc
        product = np_qmul(product, np_cayley(inc))
        chart.commit()
    assert np.abs(_strains(rod) - start).max() > 0.1  # the loop is not trivial on the way
    # close the loop: the rotation vector of conj(product) in Cayley coordinates,
    # theta = 2 vec(p)/p_0 (c(theta) = p for p_0 > 0)
    back = product * [1, -1, -1, -1]
    back *= np.sign(back[:, :1])
    th[:] = 2 * back[:, 1:] / back[:, :1]
    chart.commit()
    # round-off accumulated over four compositions of O(1) unit quaternions
    assert np.allclose(chart.q_n.x.array, q_start, rtol=0, atol=1e-13)
    assert np.allclose(_strains(rod), start, rtol=0, atol=1e-12 * np.abs(start).max())


def _state_at(dt, t_end=0.2, n_cells=4):
    """Nodal displacements and rotations at t_end (all ranks' local arrays)."""
    rod = _rod(n_cells=n_cells, distributed_loads=[DistributedLoad(
        "force", (-3.0, 0.0, 1.0), lambda t: (t / t_end) ** 3)])
    rod.set_initial_state()
    # full Newton to the library's tolerance: the Newton error stays far below the time
    # error of the finest step (~5e-7), which the default rtol 1e-6 would not ensure
    ig = TimeStepper(rod.problem, "generalized_alpha:0.8", solver_options=TIGHT)
    t = 0.0
    for _ in range(round(t_end / dt)):
        ig.step(t, dt)
        t += dt
    out = np.concatenate([rod.f["displacement"].x.array, rod.unknowns.chart.q_n.x.array])
    return rod.mesh.comm.allgather(out.tolist())


@pytest.mark.mpi
def test_lie_generalized_alpha_is_second_order():
    ref = np.concatenate(_state_at(0.2 / 320))
    errors = [np.abs(np.concatenate(_state_at(dt)) - ref).max()
              for dt in (0.2 / 10, 0.2 / 20, 0.2 / 40)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # second order: the reference's own error is (1/8)^2 = 1/64 of the finest run's, so
    # each observed order is 2 +- log2(1 + 2/64) ~ 2 +- 0.05 (the load starts smoothly,
    # (t/T)^3, so no unresolved stiff mode is excited and the error is asymptotic at once)
    assert orders == pytest.approx([2.0, 2.0], abs=0.1), (errors, orders)


@pytest.mark.mpi
def test_the_start_solves_the_mass_matrix_for_the_accelerations():
    """A straight rod at rest under a uniform force per length f, clamped at s = 0:
    the start's accelerations solve M a = F with the consistent P1 mass matrix
    rho_A h/6 [[2, 1], [1, 2]] per cell (the 2-point Gauss rule is exact for it),
    F_i = f h (interior nodes), f h/2 (the free end), a = 0 at the clamped node,
    assembled here by hand; the rotations do not accelerate (no couple: at rest the
    contact force is 0).  With the integrator's own solver (one rank: PETSc's LU;
    several: block Jacobi and GMRES)."""
    f, n = np.array([-3.0, 0.5, 1.0]), 6
    rod = _rod(n_cells=n, distributed_loads=[DistributedLoad("force", tuple(f))])
    rod.set_initial_state()
    stepper = TimeStepper(rod.problem)
    stepper.initial_accelerations(0.0)
    h, rho_A = PARAMS.length / n, PARAMS.density
    M = np.diag(np.full(n + 1, 4.0)) + np.diag(np.ones(n), 1) + np.diag(np.ones(n), -1)
    M[-1, -1] = 2.0
    M *= rho_A * h / 6
    F = np.outer(np.r_[np.ones(n), 0.5] * h, f)
    F[0] = 0.0
    M[0], M[:, 0], M[0, 0] = 0.0, 0.0, 1.0       # a_0 = 0 (the column of a_0 drops out)
    expected = np.linalg.solve(M, F)
    acc = rod.problem.accelerations
    s = acc[0].function_space.tabulate_dof_coordinates()[:, 0]
    rows = rod.mesh.comm.allgather(np.column_stack([s, acc[0].x.array.reshape(-1, 3),
                                                    acc[1].x.array.reshape(-1, 3)]))
    nodes = np.unique(np.vstack(rows), axis=0)    # ghost copies of a node are equal rows
    assert len(nodes) == n + 1
    # direct solves of an O(1)-conditioned 7x7 system: round-off (GMRES: rtol 1e-12)
    assert nodes[:, 1:4] == pytest.approx(expected, abs=1e-10)
    assert np.abs(nodes[:, 4:]).max() < 1e-10


@pytest.mark.mpi
def test_a_step_that_rotates_a_node_by_more_than_a_quarter_turn_is_refused():
    """RotationVectorChart.check_increment: |theta| = 2.5 at one node is a rotation by
    2 atan(1.25) = 1.790 rad in one step (> pi/2): a reason on every rank (MPI MAX),
    none for |theta| = 1.9 (1.517 rad)."""
    rod = _rod(n_cells=4)
    rod.set_initial_state()
    chart, theta = rod.unknowns.chart, rod.f["rotation_increment"]
    s = theta.function_space.tabulate_dof_coordinates()[:, 0]
    for size, expected in ((1.9, None), (2.5, "a node rotated by 1.79 rad in one step")):
        theta.x.array[:] = 0.0
        theta.x.array.reshape(-1, 3)[np.isclose(s, 0.75), 1] = size
        reason = chart.check_increment()
        assert rod.mesh.comm.allgather(reason) == [expected and
                                                   f"{expected} (more than pi/2)"] * \
            rod.mesh.comm.size


@pytest.mark.mpi
@pytest.mark.parametrize("turn, size", [(1.9, 1.0), (2.0 - 1e-9, 1.0), (2.0 - 1e-9, 3.0),
                                        (2.0 + 1e-9, 1.0), (2.0 + 1e-9, 0.5), (2.5, 1.0)])
def test_a_cell_turned_by_more_than_two_rad_is_refused_at_the_limit(turn, size):
    """RodModel.check_cell_turns after every step: stored rotations twisted about e_3 by
    ``turn`` rad per cell (q = size (cos(phi/2), 0, 0, sin(phi/2)), phi = turn s / h:
    closed form) pass below checks.MAX_CELL_TURN = 2 rad and are refused above it, 1e-9
    rad from the limit too (there the quick bound defers to the exact turn; round-off
    of the turn: ~1e-15 rad) and whatever the quaternions' size; the same on every rank."""
    from dolfin_rod.integrators.step_control import IntegrationError
    rod = _rod(n_cells=4)
    rod.set_initial_state()
    rod.problem.set_bcs(0.0)
    k = turn * 4 / PARAMS.length
    rod.unknowns.chart.set_nodal_rotations(lambda s: size * np.stack(
        [np.cos(k * s / 2), 0 * s, 0 * s, np.sin(k * s / 2)], axis=1))
    if turn <= 2.0:
        rod.check_cell_turns()
        return
    with pytest.raises(IntegrationError, match=f"turned by {turn:.4g} rad against its start"):
        rod.check_cell_turns()


@pytest.mark.mpi
@pytest.mark.parametrize("turn", [0.1, 1.9, 2.0 - 1e-9, 2.0 + 1e-9, 2.5])
def test_a_commit_refuses_a_cell_turned_by_more_than_two_rad(turn):
    """After a step (problem.after_step: the chart's commit normalises the stored
    rotations, then the cell-turn check on quaternions of unit size, whose bounds are the
    sum of |q_b - q_a|^2 over the cells (0.1 rad a cell), then each cell's q_a . q_b
    (1.9 rad), then the exact turn (1e-9 rad from the limit)): the same answers as
    check_cell_turns above, for stored rotations of size 3 twisted by ``turn`` rad per
    cell (closed form), on every rank."""
    from dolfin_rod.integrators.step_control import IntegrationError
    rod = _rod(n_cells=4)
    rod.set_initial_state()
    rod.problem.set_bcs(0.0)
    k = turn * 4 / PARAMS.length
    rod.unknowns.chart.set_nodal_rotations(lambda s: 3.0 * np.stack(
        [np.cos(k * s / 2), 0 * s, 0 * s, np.sin(k * s / 2)], axis=1))
    if turn <= 2.0:
        rod.problem.after_step()
        q = rod.unknowns.chart.q_n.x.array.reshape(-1, 4)
        assert np.allclose(np.linalg.norm(q, axis=1), 1.0, rtol=0, atol=1e-15)
        return
    with pytest.raises(IntegrationError, match=f"turned by {turn:.4g} rad against its start"):
        rod.problem.after_step()


@pytest.mark.mpi
def test_a_refused_step_is_redone_as_two_half_steps():
    """problem.check_step refusing the first attempt (as check_increment refuses a
    spurious root): the state is restored and the step done as two half steps, the same
    (to round-off) as two steps of half the size from the start."""
    def displacements(dt, refuse_first):
        rod = _rod(end_loads=[EndLoad("force", (-2.0, 0.5, 0.0))])
        rod.set_initial_state()
        refusals = [refuse_first]       # the first call's answer, then None
        rod.problem.check_step = lambda: "refused" if refusals and refusals.pop() else None
        stepper = TimeStepper(rod.problem)
        stepper.run(0.0, 0.02, dt)
        x = np.concatenate(rod.mesh.comm.allgather(rod.f["displacement"].x.array))
        return x, stepper.stats
    (x_cut, cut), (x_half, half) = displacements(0.02, True), displacements(0.01, False)
    assert (cut.rejected, cut.steps, half.rejected, half.steps) == (1, 2, 0, 2)
    assert np.abs(x_half).max() > 1e-4
    assert np.allclose(x_cut, x_half, rtol=0, atol=1e-13)


def _three_steps(params, n_cells):
    rod = _rod(params, n_cells=n_cells,
               distributed_loads=[DistributedLoad("force", (-3.0, 0.0, 1.0))])
    rod.set_initial_state()
    ig = TimeStepper(rod.problem)
    for k in range(3):
        ig.step(0.01 * k, 0.01)
    return np.concatenate([rod.f["displacement"].x.array, rod.unknowns.chart.q_n.x.array,
                           rod.r["rotation_increment"].x.array])


@pytest.mark.mpi
def test_cached_step_forms_give_the_fresh_forms_results():
    other = RodParameters(length=2.0, A=(1.0, 2.0, 3.0), B=(4e2, 5e2, 6e2), density=1.0,
                          section_inertia=(2e-3, 3e-3))
    form_cache.clear()
    _three_steps(other, 6)                      # compiles; other mesh and data
    cached = _three_steps(PARAMS, 5)            # binds the same kernels to its own data
    form_cache.clear()
    fresh = _three_steps(PARAMS, 5)
    # the same kernels on the same data: equal to round-off (bitwise in serial; the
    # parallel Krylov solve's reductions may round differently: 1e-17 measured)
    assert np.allclose(cached, fresh, rtol=0, atol=1e-14 * np.abs(fresh).max())
    keys = {form_cache.structure_key(RodModel(PARAMS, n_cells=n, model=m).problem.residual)
            for n, m in ((5, "hyperelastic"), (7, "hyperelastic"), (5, "evolving"))}
    assert len(keys) == 2  # the structure, not the mesh size, decides


@pytest.mark.mpi
def test_step_forms_from_the_disk_cache_give_the_fresh_forms_results():
    form_cache.clear()
    fresh = _three_steps(PARAMS, 5)             # compiles; records the kernels on disk
    rod = _rod(PARAMS, n_cells=5,
               distributed_loads=[DistributedLoad("force", (-3.0, 0.0, 1.0))])
    key = TimeStepper(rod.problem).structure_key
    form_cache.clear(disk=False)                # as a new process: memory empty
    # serial: the entry comes from disk; under MPI the disk cache is off (a rank's miss
    # would deadlock the collective JIT of the others' hit), so nothing is found
    assert (form_cache.lookup(key, rod.mesh.comm) is not None) == (rod.mesh.comm.size == 1)
    form_cache.clear(disk=False)
    from_disk = _three_steps(PARAMS, 5)
    # the same kernels on the same data: equal to round-off (see the test above)
    assert np.allclose(from_disk, fresh, rtol=0, atol=1e-14 * np.abs(fresh).max())



@pytest.mark.mpi
def test_step_kernels_are_kept_apart_per_cpu_and_flags(monkeypatch):
    """The step kernels are built for the host's instruction set (form_cache.KERNEL_FLAGS:
    -march=native on x86-64) and their flags name the host CPU, so that a cache shared by
    several machines (a home folder on NFS) never hands one a kernel built for another:
    with another CPU's flags the same form compiles to another FFCx module, and the disk
    entry recorded on this CPU is not found (serial: under MPI the disk cache is off).
    DOLFIN_ROD_KERNEL_FLAGS replaces the flags."""
    import ufl
    from dolfinx import fem, mesh
    from mpi4py import MPI

    domain = mesh.create_unit_interval(MPI.COMM_WORLD, 4)
    f = fem.Function(fem.functionspace(domain, ("Lagrange", 1)))
    form = f * f * ufl.dx
    here = form_cache.compile_forms(form)
    key = form_cache.structure_key([form], "kernel flags test")
    form_cache.store(key, [here], [form], [f])
    form_cache.clear(disk=False)                    # as a new process on this CPU ...
    # ... finds its entry on disk (serial; see test_step_forms_from_the_disk_cache_...)
    assert (form_cache.lookup(key, domain.comm) is not None) == (domain.comm.size == 1)
    flags = [x for x in form_cache.KERNEL_FLAGS if not x.startswith("-DDOLFIN_ROD_HOST_CPU=")]
    assert len(flags) == len(form_cache.KERNEL_FLAGS) - 1      # the CPU is named
    monkeypatch.setattr(form_cache, "KERNEL_FLAGS", [*flags, "-DDOLFIN_ROD_HOST_CPU=other"])
    form_cache.clear(disk=False)                    # a process on another CPU ...
    assert form_cache.lookup(key, domain.comm) is None           # ... does not find this CPU's entry
    there = form_cache.compile_forms(form)          # and compiles its own module
    assert there.module.__file__ != here.module.__file__
    assert np.isclose(fem.assemble_scalar(there), fem.assemble_scalar(here))
    form_cache.clear(disk=False)
    monkeypatch.setenv("DOLFIN_ROD_KERNEL_FLAGS", "-O2 -g0")
    assert form_cache.kernel_flags() == ["-O2", "-g0"]
    # flags the compiler refuses: an error naming the variable
    monkeypatch.setenv("DOLFIN_ROD_KERNEL_FLAGS", "-fno-such-flag-for-dolfin-rod")
    monkeypatch.setattr(form_cache, "KERNEL_FLAGS", form_cache.kernel_flags())
    with pytest.raises(RuntimeError, match="DOLFIN_ROD_KERNEL_FLAGS='-fno-such-flag"):
        form_cache.compile_forms(2.0 * f * ufl.dx)

# -- the rod's physics with rotation vectors ----------------------------------------------


def _history(rod, t_end, dt, scheme="generalized_alpha:0.8"):
    rod.set_initial_state()
    history: list[dict] = []
    stepper = TimeStepper(rod.problem, scheme, solver_options=TIGHT)
    stepper.run(0.0, t_end, dt, observer=lambda t, s: history.append(rod.diagnostics(t)))
    return history


def _series(history, key):
    return np.array([h[key] for h in history])


@pytest.mark.mpi
def test_reactions_equal_the_quaternion_rods_reactions():
    """Same nodal state (at rest) in both discretisations: the reaction forms test the
    same residual (internal forces on the 1-point rule, the weight: exact for a constant
    load times the hat function) with the same nodal virtual motion of the end node (a
    translation, or a spatial rotation: delta q_a = (0, e) q_a / 2 and delta theta_a =
    R(q_a)^T e), so the clamp reactions agree to round-off."""
    weight = [DistributedLoad("force", (-3.0, 0.5, 1.0))]
    rod = _rod(start="clamped", end="free", distributed_loads=weight)
    _deformed(rod)
    th = rod.f["rotation_increment"].x.array.reshape(-1, 3)
    chart = rod.unknowns.chart
    q_nodes = np_qmul(chart.q_n.x.array.reshape(-1, 4), np_cayley(th))
    clamp = np.isclose(chart.node_s, 0.0)
    th[clamp] = 0.0                                    # the clamp: theta = 0, q_n = 1
    q_nodes[clamp] = chart.q_n.x.array.reshape(-1, 4)[clamp] = (1.0, 0, 0, 0)
    x = rod.f["displacement"].x.array.reshape(-1, 3)
    x[clamp] = 0.0
    ref = RodModel(PARAMS, n_cells=6, model="hyperelastic", rotations="quaternion",
                   distributed_loads=weight)
    ref.set_initial_state()
    ref.f["quaternion"].x.array[:] = q_nodes.ravel()
    ref.f["displacement"].x.array[:] = x.ravel()
    mine, theirs = rod.diagnostics(0.0), ref.diagnostics(0.0)
    keys = [k for k in theirs if k.startswith("reaction_")]
    assert len(keys) == 6 and set(keys) <= set(mine)
    scale = max(abs(theirs[k]) for k in keys)
    assert scale > 1.0                                   # a loaded, deformed state
    # round-off of the assembled forms of O(1e2) stiffness times O(1) strains
    for k in keys:
        assert mine[k] == pytest.approx(theirs[k], abs=1e-11 * scale), k


def _power_defect(model_name, dt, **kw):
    """|E(T) - E(0) + int xi dt - int P dt| / |E(T)|, E = free + kinetic energy."""
    visc = dict(M=(0.05,) * 3, N=(0.05,) * 3)
    if model_name == "evolving":
        visc.update(M_d=(0.5,) * 3, N_d=(5.0,) * 3)
    p = RodParameters(A=(1.0, 1.0, 1.0), B=(50.0, 50.0, 50.0), density=1.0,
                      section_inertia=0.01, drag=0.3, **visc)
    rod = RodModel(p, n_cells=6, model=model_name, **kw)
    assert rod.rotations == "rotation_vector"
    h = _history(rod, 1.0, dt)
    t = _series(h, "time")
    energy = _series(h, "free_energy") + _series(h, "kinetic_energy")
    net = _series(h, "load_power") - _series(h, "dissipation_rate")
    return abs(energy[-1] - energy[0] - np.trapezoid(net, t)) / abs(energy[-1])


LOADED = dict(end_loads=[EndLoad("force", (0.4, 0.0, 0.1), loads.smooth_step(1.0, 0.5)),
                         EndLoad("couple", (0.0, 0.2, 0.0), loads.smooth_step(1.0, 0.5),
                                 follower=True)],
              distributed_loads=[DistributedLoad("force", (0.0, -0.3, 0.0),
                                                 loads.smooth_step(1.0, 0.3)),
                                 DistributedLoad("couple", (0.1, 0.0, 0.05),
                                                 loads.smooth_step(1.0, 0.3), follower=True)])
TWISTED = dict(start="clamped", end="pinned",
               end_rotation={"start": lambda t: np.array([0.3, 0.0, 1.0]) * 3 * t**2},
               distributed_loads=[DistributedLoad("force", (0.0, -0.3, 0.0))])


@pytest.mark.parametrize("model_name,case", [
    pytest.param("kelvin_voigt", "loaded", marks=pytest.mark.mpi),
    ("evolving", "loaded"),          # under mpirun: each model and each case once
    pytest.param("evolving", "twisted", marks=pytest.mark.mpi)])
def test_power_balance_at_second_order(model_name, case):
    """d/dt(free + kinetic energy) + int xi + drag = power of the loads and of the moving
    clamp (docs/corrections.md identities), with Kelvin-Voigt strain rates along the angular
    velocities, evolving natural strains, linear drag, dead and follower loads at the
    end and along the rod, and a clamp turning about a fixed axis with the other end
    pinned: the defect falls like dt^2 (generalized-alpha and the trapezoidal rule are
    second order).  A wrong strain rate, load power or reaction power leaves an O(1)
    defect that does not converge."""
    kw = LOADED if case == "loaded" else TWISTED
    defects = [_power_defect(model_name, dt, **kw) for dt in (0.05, 0.025)]
    rate = np.log2(defects[0] / defects[1])
    # observed order 2 -0.2 (pre-asymptotic margin, as tests/test_rod.py's power tests)
    assert rate > 1.8, (defects, rate)


@pytest.mark.mpi
def test_prescribed_end_rotation_is_followed_exactly():
    """theta_end = c^-1(conj(q_n,end) q_end(t)) makes the end's rotation q_n c(theta) the
    prescribed one at every step, over more than a full turn (round-off per step)."""
    axis = np.array([0.6, 0.0, 0.8])
    turn = loads.smooth_step(8.0, 1.0)                     # 8 rad: past 2 pi
    rod = _rod(start="clamped", end="clamped",
               end_rotation={"end": lambda t: axis * float(turn(t))})
    h = _history(rod, 1.0, 0.05)
    for d in h:
        q = np_quaternion_from_rotation_vector(axis * float(turn(d["time"])))
        tip = np.array([d[f"tip_quaternion_{i}"] for i in range(4)])
        # round-off of ~20 compositions of unit quaternions (O(1e-16) each)
        assert np.abs(tip - q).max() < 1e-12 or np.abs(tip + q).max() < 1e-12, d["time"]


@pytest.mark.mpi
def test_stress_free_helix_stays_at_rest():
    """A helix of the reference curvature is stress free: without loads nothing moves
    (the nodal rotations are set from the helix, the strains are its discrete strains)."""
    p = RodParameters(A=(1.0, 1.5, 0.8), B=(30.0, 40.0, 50.0), density=1.0,
                      section_inertia=0.01, reference_curvature=(0.9, 0.0, 1.7))
    rod = RodModel(p, n_cells=8, model="hyperelastic", start="clamped", end="free")
    h = _history(rod, 0.2, 0.05)
    # energies of O(1e2) stiffness times round-off strains squared
    assert max(_series(h, "free_energy")) < 1e-20
    assert max(_series(h, "kinetic_energy")) < 1e-20
    tips = np.array([[d[f"tip_position_{c}"] for c in "xyz"] for d in h])
    assert np.abs(tips - tips[0]).max() < 1e-13


@pytest.mark.mpi
def test_one_point_rule_is_the_two_point_gauss_rule():
    """RotationVectorChart.one_point_rule evaluates a 2-point Gauss integral as a 1-point
    integral of the integrand at the two Gauss points: the residual and Jacobian of a
    nonlinear integrand of P1 fields, a per-cell field and s (the terms of the inertia:
    T(theta) dTheta, products of the unknowns) equal DOLFINx's own 2-point Gauss rule."""
    import dolfinx.fem as fem
    import dolfinx.fem.petsc as fem_petsc
    import ufl
    from mpi4py import MPI

    from dolfin_rod.rod.rotation_vector import tangent
    rod = _rod(n_cells=7)
    _deformed(rod)
    theta, x = rod.f["rotation_increment"], rod.f["displacement"]
    mesh, chart = rod.mesh, rod.unknowns.chart
    cell_field = fem.Function(fem.functionspace(mesh, ("DG", 0)))
    cell_field.x.array[:] = 1.0 + np.arange(len(cell_field.x.array)) % 3
    s = ufl.SpatialCoordinate(mesh)[0]
    dx_2 = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 2})
    dx_1 = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1})
    v = ufl.TestFunction(theta.function_space)
    g = (cell_field * (1 + s * s) * ufl.inner(ufl.cross(theta, x) + x, tangent(theta, v))
         + ufl.dot(chart.q, chart.q) * ufl.inner(x, v))
    reference = g * dx_2
    mine = chart.one_point_rule(reference.integrals(), dx_1)
    assert all(itg.metadata() == dx_1.metadata() for itg in mine.integrals())
    comm = mesh.comm
    for form in (lambda F: F, lambda F: ufl.derivative(F, theta)):
        values = []
        for F in (reference, mine):
            compiled = fem.form(form(F))
            if compiled.rank == 1:
                values.append(fem.assemble_vector(compiled).array.copy())
            else:
                A = fem_petsc.assemble_matrix(compiled)
                A.assemble()
                values.append(A.convert("dense").getDenseArray().copy())
        size = comm.allreduce(np.abs(values[0]).max(), op=MPI.MAX)
        error = comm.allreduce(np.abs(values[1] - values[0]).max(), op=MPI.MAX)
        # same quadrature, other evaluation order: round-off (1e-13 of the entries' size)
        assert error <= 1e-13 * size and size > 0.1


def _loaded_run(solver_options):
    """Displacements after 10 steps of a 6-cell rod swinging under a tip load, and the
    stepper (its solver's counts)."""
    rod = _rod(end_loads=[EndLoad("force", (-2.0, 0.5, 0.0))])
    rod.set_initial_state()
    stepper = TimeStepper(rod.problem, solver_options=solver_options)
    stepper.run(0.0, 0.2, 0.02)
    return rod.mesh.comm.allgather(rod.f["displacement"].x.array.tolist()), stepper


@pytest.mark.mpi
def test_default_jacobian_reuse_solves_the_same_steps():
    """The default Newton (jacobian_reuse_ratio: a new Jacobian at each step's first
    iteration and after an iteration that reduced the residual less than 10-fold, else
    the last one and its LU kept) against full Newton (a Jacobian every iteration; a
    snes_lag_* option replaces the reuse rule), both to rtol 1e-10: the same steps, fewer
    Jacobians than iterations, at least one per step."""
    tight = {"snes_rtol": 1e-10}
    x_reuse, reuse = _loaded_run(tight)
    x_full, full = _loaded_run({**tight, "snes_lag_jacobian": 1})
    steps = reuse.stats.steps
    assert full.solver.counts["jacobian"] == full.stats.newton_iterations
    assert steps <= reuse.solver.counts["jacobian"] < reuse.stats.newton_iterations
    # both converged to rtol 1e-10 of a residual whose Jacobian is O(1) well conditioned
    # at this size: the displacements (O(0.1)) agree to ~1e-10, 1e-8 leaves 100x margin
    assert np.allclose(np.concatenate(x_reuse), np.concatenate(x_full), rtol=0, atol=1e-8)


QUASI_STATIC = RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2))
KELVIN_VOIGT = RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2),
                             M=(0.1, 0.1, 0.1))
NO_ROTARY_INERTIA = RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2),
                                  density=2.0, section_inertia=(1e-3, 0.0))


@pytest.mark.mpi       # under mpirun: both ranks refuse alike, none hangs (4 cells: two per rank)
@pytest.mark.parametrize("make, match", [
    # an unknown name, and rotation vectors where they do not apply
    (lambda: RodModel(PARAMS, n_cells=4, model="hyperelastic", rotations="euler"),
     "rotations must be one of"),
    (lambda: RodModel(KELVIN_VOIGT, n_cells=4, model="kelvin_voigt",
                      rotations="rotation_vector"), "Kelvin-Voigt viscosity"),
    (lambda: RodModel(QUASI_STATIC, n_cells=4, model="hyperelastic", start="pinned", end="free",
                      rotations="rotation_vector"), "no end holds"),
    (lambda: RodModel(PARAMS, n_cells=4, model="hyperelastic", variant="uniform",
                      rotations="rotation_vector"), "uniform variant"),
    (lambda: RodModel(NO_ROTARY_INERTIA, n_cells=4, model="hyperelastic",
                      rotations="rotation_vector"), "without rotary inertia section_inertia > 0"),
])
def test_rotation_choice_is_checked(make, match):
    with pytest.raises(ValueError, match=match):
        make()


@pytest.mark.mpi
def test_a_rod_without_rotary_inertia_swings_on_quaternions():
    """rho_A > 0 with I22 = 0: the rotation-group integrator's start would solve a
    singular mass matrix for the angular accelerations (the moment balance is then
    algebraic), so "auto" takes quaternions and their first-order system; the step
    converges and the rod moves under its load, the same as with explicit quaternions."""
    def tip(**kwargs):
        rod = RodModel(NO_ROTARY_INERTIA, n_cells=4, model="hyperelastic", end_loads=[
            EndLoad("force", (-2.0, 0.5, 0.0))], **kwargs)
        rod.set_initial_state()
        TimeStepper(rod.problem).run(0.0, 0.05, 0.01)
        return rod.rotations, np.concatenate(rod.mesh.comm.allgather(
            rod.f["displacement"].x.array))
    (auto, x_auto), (_, x_quaternion) = tip(), tip(rotations="quaternion")
    assert auto == "quaternion"
    # the same model and integrator: identical to round-off; the tip load moves the rod
    assert np.allclose(x_auto, x_quaternion, rtol=0, atol=1e-12)
    assert np.abs(x_auto).max() > 1e-3


@pytest.mark.mpi
def test_other_integrators_refuse_rotation_vectors_naming_the_way_out():
    from dolfin_rod.integrators.ts import TSIntegrator
    rod = _rod(n_cells=4)       # >= 2 cells per rank under mpirun -n 2
    for build in (lambda: TimeStepper(rod.problem, "bdf2"), lambda: TSIntegrator(rod.problem)):
        with pytest.raises(ValueError, match="rotations='quaternion'"):
            build()
    assert TimeStepper(rod.problem, "generalized_alpha:0.5").rho_inf == 0.5
