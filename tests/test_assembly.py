"""What the speed options may change: the Newton path, never the solution.

References: DOLFINx's blocked assembly (BlockedSystem), which the mixed-element layout
(MonolithicSystem) must reproduce block by block at a random state (residual, and the
Jacobian's action on a random vector); full Newton from the constant predictor with
the default LU, which the linear predictor and PETSc's own LU (solvers.NATIVE_LU) must
reproduce to the Newton tolerance.
"""

from __future__ import annotations

import dolfinx
import dolfinx.fem as fem
import numpy as np
import pytest
import ufl

from dolfin_rod import loads
from dolfin_rod.fem.assembly import BlockedSystem, MonolithicSystem, block_system
from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, EndLoad, RodModel, RodParameters
from dolfin_rod.fem.solvers import NATIVE_LU
from dolfin_rod.torsion.model import TorsionModel, TorsionParameters


def creeping_cantilever(n_cells=4):
    p = RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2), density=2.0,
                      section_inertia=1e-3, A_d=(0.3, 0.4, 0.2), B_d=(1e2, 1e2, 3e2),
                      M_d=(0.1, 0.1, 0.1), N_d=(10.0, 10.0, 30.0))
    model = RodModel(p, n_cells=n_cells, model="evolving", variant="local",
                     rotations="quaternion",           # the blocked/mixed layouts' case
                     distributed_loads=[DistributedLoad("force", (-5.0, 0.0, 0.0))],
                     end_loads=[EndLoad("couple", (0.0, 0.1, 0.2), loads.ramp(1.0, 0.3),
                                        follower=True)])
    model.set_initial_state()
    return model


def step_forms(problem, scheme):
    """The UFL step residual a TimeStepper would solve, and its Dirichlet conditions."""
    st = TimeStepper(problem, scheme)
    st.dt.value = 0.01
    return st.step_forms(), problem.bcs


def owned(f):
    im = f.function_space.dofmap.index_map
    return im.size_local * f.function_space.dofmap.index_map_bs


def in_blocks(system, vec, fields):
    """A vector of either layout, split into the blocks' owned entries."""
    a = vec.getArray(readonly=True)
    if isinstance(system, MonolithicSystem):
        return [a[m[:owned(f)]] for f, m in zip(fields, system.block_dofs)]
    offsets = np.cumsum([0] + [owned(f) for f in fields])
    return [a[offsets[j]:offsets[j + 1]] for j in range(len(fields))]


@pytest.mark.mpi
@pytest.mark.parametrize("scheme", ["backward_euler", "generalized_alpha"])
def test_mixed_element_layout_reproduces_blocked_assembly(scheme):
    """Residual and Jacobian action agree block by block to 1e-7 relative: the layouts
    differ only in the quadrature degree UFL estimates for integrals without an explicit
    degree (the mixed element's degree is the largest of its blocks'), which changes
    non-polynomial integrands at the 1e-8 level here; a missed term or a wrong rule
    shows as O(1) (FFCx's mixed vertex + Gauss kernels did, hence one kernel per rule)."""
    model = creeping_cantilever()
    fields = model.problem.fields
    rng = np.random.default_rng(1)
    for f in fields:
        f.x.array[:] += 0.05 * rng.standard_normal(f.x.array.shape)
        f.x.scatter_forward()
    F, bcs = step_forms(model.problem, scheme)
    model.problem.set_bcs(0.01)
    directions = [fem.Function(f.function_space) for f in fields]
    for d in directions:
        d.x.array[:] = rng.standard_normal(d.x.array.shape)
    # group 1: a direction for the Jacobian action, set into each layout's vectors
    systems = [block_system(F, [fields, directions], bcs=bcs, monolithic=m)
               for m in (False, True)]
    assert [type(s) for s in systems] == [BlockedSystem, MonolithicSystem]
    results = []
    for s in systems:
        s.get(0, s.x)
        s.residual(s.x, s.b)
        s.jacobian(s.A)
        v, Jv = s.x.duplicate(), s.x.duplicate()
        s.get(1, v)
        s.A.mult(v, Jv)
        results.append((in_blocks(s, s.b, fields), in_blocks(s, Jv, fields)))
    for kind in (0, 1):
        for f, blocked, mixed in zip(fields, results[0][kind], results[1][kind]):
            scale = max(np.abs(blocked).max(), 1e-300)
            assert np.abs(mixed - blocked).max() <= 1e-7 * scale, (kind, f.name)
        assert any(np.abs(b).max() > 1e-3 for b in results[0][kind])  # not vacuous


@pytest.mark.mpi
def test_layout_choice_follows_the_evolution_variant():
    """Real spaces (the uniform variant's global natural twist) need the blocked layout."""
    for variant, expected in (("local", MonolithicSystem), ("uniform", BlockedSystem)):
        model = TorsionModel(TorsionParameters(mu=0.1, mu_d=0.5), n_cells=4, variant=variant,
                             end_torsion=loads.constant(1.0))
        p = model.problem
        assert isinstance(block_system(p.residual, [p.fields], bcs=p.bcs), expected)


@pytest.mark.mpi
def test_linear_predictor_saves_newton_iterations_not_accuracy():
    """The predictor y_n + dt dy/dt_n changes only Newton's starting point: same states to
    the Newton tolerance (rtol 1e-10 of O(1) residuals: 1e-8 on positions), fewer
    iterations on smooth dynamics (measured 150 vs 172 on the peer benchmark's creep)."""
    runs = []
    for predictor in TimeStepper.PREDICTORS:
        model = creeping_cantilever(8)
        st = TimeStepper(model.problem, "generalized_alpha", predictor=predictor)
        st.run(0.0, 0.2, 0.01)
        runs.append((model.f["displacement"].x.array.copy(), st.stats.newton_iterations))
    (x_lin, its_lin), (x_const, its_const) = runs
    assert np.abs(x_const).max() > 0.05  # the rod moved
    assert x_lin == pytest.approx(x_const, abs=1e-8)
    assert its_lin < its_const, (its_lin, its_const)
    with pytest.raises(ValueError, match="predictor"):
        TimeStepper(model.problem, predictor="quadratic")


@pytest.mark.mpi
def test_native_lu_gives_the_mumps_states_and_is_refused_in_parallel():
    """PETSc's LU with the multipliers' zero diagonals permuted away solves the same
    Newton systems as the default LU (SuperLU, pivoting): same states to the Newton
    tolerance.  Under MPI
    it does not exist, and asking for it is a ValueError before any assembly."""
    model = creeping_cantilever(8)
    if model.mesh.comm.size > 1:
        with pytest.raises(ValueError, match="pc_factor_mat_solver_type"):
            TimeStepper(model.problem, "generalized_alpha", solver_options=NATIVE_LU).step(0.0, 0.01)
        return
    states = []
    for options in ({}, NATIVE_LU):
        model = creeping_cantilever(8)
        TimeStepper(model.problem, "generalized_alpha", solver_options=options).run(0.0, 0.2, 0.01)
        states.append(model.f["displacement"].x.array.copy())
    assert np.abs(states[0]).max() > 0.05
    assert states[1] == pytest.approx(states[0], abs=1e-8)


@pytest.mark.mpi
def test_a_solver_takes_its_options_away():
    """A solver's PETSc options leave the options database with it: under mpirun the
    default block-Jacobi sub-solver options are read at the first solve only, and PETSc
    printed "WARNING! There are options you set that were not used!" at exit for every
    stepper that never stepped."""
    import gc

    from petsc4py import PETSc
    model = RodModel(RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2),
                                   density=2.0, section_inertia=1e-3), n_cells=4)
    stepper = TimeStepper(model.problem)
    prefix = stepper.solver.prefix

    def left():
        return [k for k in PETSc.Options().getAll() if k.startswith(prefix)]
    assert "snes_rtol" in [k[len(prefix):] for k in left()]
    del stepper
    gc.collect()
    assert left() == []


def _random_state(model, seed):
    """Every unknown and rate of the model at random values (a state no test shortcut
    can make simple: every diagnostic form is then nonzero), from the initial state
    (rotation vectors: the stored rotations)."""
    model.set_initial_state()
    rng = np.random.default_rng(seed)
    for f in [*model.problem.fields, *model.problem.rates]:
        f.x.array[:] = 0.05 * rng.standard_normal(f.x.array.shape)
        f.x.scatter_forward()


def _kelvin_voigt_with_drag():
    """Rotation vectors, Kelvin-Voigt viscosity and drag: dissipation on the 1-point and
    the 2-point rule (on main before the fix: the fused kinetic energy 26 % off)."""
    return RodModel(RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2),
                                  M=(0.1, 0.2, 0.3), N=(1.0, 2.0, 3.0), density=2.0,
                                  section_inertia=1e-3, drag=0.3),
                    n_cells=4, model="kelvin_voigt", rotations="rotation_vector",
                    distributed_loads=[DistributedLoad("force", (-5.0, 0.0, 1.0))])


def _integral_by_integral(form, comm) -> float:
    """A scalar form as the sum of its integrals assembled one at a time (one quadrature
    rule per kernel: quadrature_rules.py), MPI-summed."""
    from mpi4py import MPI
    return comm.allreduce(sum(fem.assemble_scalar(fem.form(ufl.Form([itg])))
                              for itg in form.integrals()), op=MPI.SUM)


@pytest.mark.mpi
@pytest.mark.parametrize("build", [
    creeping_cantilever,
    lambda: RodModel(RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2),
                                   density=2.0, section_inertia=(1e-3, 2e-3), drag=0.3), n_cells=4,
                     model="hyperelastic", end_loads=[EndLoad("force", (0.0, 1.0, -2.0))],
                     distributed_loads=[DistributedLoad("force", (-5.0, 0.0, 1.0))]),
    _kelvin_voigt_with_drag,
    lambda: TorsionModel(TorsionParameters(mu=0.1, mu_d=0.5, nu=0.2), n_cells=4,
                         variant="uniform", end_torsion=loads.constant(1.0))],
    ids=["quaternions, creep", "rotation vectors, drag", "rotation vectors, Kelvin-Voigt",
         "torsion, uniform variant"])
def test_diagnostics_in_one_assembly_equal_the_forms_one_by_one(build):
    """model_base.FormSums (all diagnostic forms in one vector assembly per quadrature
    rule) against DOLFINx's scalar assembly of each integral of each form, MPI-summed:
    the same sums of the same quadrature points, so equal to round-off (1e-12 relative to
    the largest value).  Each integral alone: a form's own scalar assembly can be wrong
    (FFCx, a kernel with the 1-point rule and another: quadrature_rules.py; the
    Kelvin-Voigt rod's dissipation rate)."""
    model = build()
    _random_state(model, seed=4)
    fused = model.assembled_diagnostics(0.2)
    one_by_one = {key: _integral_by_integral(form, model.mesh.comm)
                  for key, form in model.diagnostic_forms.items()}
    scale = max(abs(v) for v in one_by_one.values())
    assert scale > 1e-3
    for key, value in one_by_one.items():
        assert fused[key] == pytest.approx(value, rel=0, abs=1e-12 * scale), key


def test_one_kernel_per_quadrature_rule():
    """FormSums of e = u sin(u) on the 1-point rule, e on the degree-4 rule (3 Gauss
    points) and their sum, u = s on one cell [0, 1]: the midpoint value 0.5 sin(0.5), the
    3-point Gauss-Legendre sum (0.30117) and their sum, to round-off.  One FFCx kernel
    with both rules gives the midpoint value 0.23971 for the second too
    (quadrature_rules.py)."""
    from mpi4py import MPI

    from dolfin_rod.fem.fe_model import FormSums
    mesh = dolfinx.mesh.create_unit_interval(MPI.COMM_SELF, 1)
    u = fem.Function(fem.functionspace(mesh, ("Lagrange", 1)))
    u.interpolate(lambda x: x[0])
    e = ufl.sin(u) * u
    dx = {k: ufl.dx(domain=mesh, metadata={"quadrature_degree": k}) for k in (1, 4)}
    points, weights = np.polynomial.legendre.leggauss(3)
    s = (points + 1) / 2
    midpoint, gauss = 0.5 * np.sin(0.5), np.sum(weights / 2 * s * np.sin(s))
    fused = FormSums(mesh, [e * dx[1], e * dx[4], e * dx[1] + e * dx[4]])()
    assert fused == pytest.approx([midpoint, gauss, midpoint + gauss], rel=1e-14)


@pytest.mark.mpi
def test_a_residual_near_its_nodes_is_the_full_residual_there():
    """model_base.near_nodes (cell integrals on the cells touching the given nodes only,
    as the reactions use it) against the full residual at those nodes (both ends and an
    interior node), at a random state: their test functions vanish on every other cell,
    so the values agree to round-off; elsewhere the restricted vector is mostly 0."""
    from dolfin_rod.fem.fe_model import NodeValues, near_nodes, nodal_residual
    model = creeping_cantilever(n_cells=6)
    _random_state(model, seed=7)
    s_nodes = [0.0, 0.5, 1.0]
    for block in ("displacement", "quaternion"):
        form = model.residual[block]
        V = model.problem.fields[model.names.index(block)].function_space
        nodes = NodeValues(V, s_nodes)
        full = nodal_residual(fem.form(form), nodes)
        near = nodal_residual(fem.form(near_nodes(form, model.mesh, s_nodes)), nodes)
        assert np.abs(full).max() > 1e-3
        assert near == pytest.approx(full, rel=0, abs=1e-12 * np.abs(full).max())
        elsewhere = nodal_residual(fem.form(near_nodes(form, model.mesh, [0.0])), nodes)
        assert np.abs(elsewhere[1]).max() < 1e-12 < np.abs(full[1]).max()


@pytest.mark.mpi
def test_the_default_lu_pivots_on_one_rank_and_is_mumps_on_several():
    """solvers.petsc_options: SuperLU (partial pivoting) serially, MUMPS under MPI; a
    user's solver type wins; another preconditioner gets no LU solver type (PETSc would
    report it unused)."""
    from mpi4py import MPI

    from dolfin_rod.fem.solvers import petsc_options
    comm = MPI.COMM_WORLD
    assert petsc_options(comm, None)["pc_factor_mat_solver_type"] == \
        ("superlu" if comm.size == 1 else "mumps")
    assert petsc_options(MPI.COMM_SELF, None)["pc_factor_mat_solver_type"] == "superlu"
    chosen = {"pc_factor_mat_solver_type": "superlu_dist"}
    assert petsc_options(comm, chosen)["pc_factor_mat_solver_type"] == "superlu_dist"
    assert "pc_factor_mat_solver_type" not in petsc_options(comm, {"pc_type": "jacobi"})


@pytest.mark.mpi
def test_default_newton_keeps_its_jacobian_also_on_large_quasi_static_load_steps():
    """BlockSNES's default (solvers.REUSE_RATIO: the Jacobian kept while each iteration
    reduces the residual 10-fold, a new one at each solve's start) against full Newton
    (jacobian_reuse_ratio = 0) on a quasi-static rod rolled up by a follower couple in 4
    load steps of a quarter circle each: the same states to the Newton tolerance (rtol
    1e-10 of an O(1)-conditioned residual: 1e-8 leaves a wide margin), reached with more,
    cheaper iterations (the kept Jacobian converges linearly)."""
    EI = 2.0

    def rolled(options):
        model = RodModel(RodParameters(length=1.0, A=(EI, EI, 1.0), B=(1e3, 1e3, 1e3)),
                         n_cells=8, model="hyperelastic", end_loads=[EndLoad(
                             "couple", (2 * np.pi * EI, 0.0, 0.0), loads.ramp(1.0, 1.0),
                             follower=True)])
        model.set_initial_state()
        stepper = TimeStepper(model.problem, "backward_euler", solver_options=options)
        stepper.run(0.0, 1.0, 0.25)
        x = np.concatenate(model.mesh.comm.allgather(model.f["displacement"].x.array))
        return x, stepper.stats.newton_iterations
    (x_default, its_default), (x_full, its_full) = rolled(None), rolled(
        {"jacobian_reuse_ratio": 0})
    assert np.abs(x_full).max() > 0.5               # rolled up: the tip moved by ~L
    assert np.allclose(x_default, x_full, rtol=0, atol=1e-8)
    assert its_default > its_full, (its_default, its_full)


# an SNES option outside solvers.PLAIN_NEWTON that changes nothing here (the function
# count limit, far above any solve's): the solves then go through SNESSolve
THROUGH_SNES = {"snes_max_funcs": 100000}


def _recorded_solves(monkeypatch, build, options, run):
    """The residual norms of every Newton iterate (BlockSNES._residual), the final
    displacements, the Newton iterations and which loop ran: BlockSNES's own
    (_plain_newton) or SNESSolve, of ``run(stepper)`` on the model ``build()``."""
    from dolfin_rod.fem import solvers
    norms, own = [], []
    residual, plain = solvers.BlockSNES._residual, solvers.BlockSNES._plain_newton

    def recorded(self, snes, x, b):
        residual(self, snes, x, b)
        norms.append(self._residual_norm)

    def counted(self):
        own.append(1)
        plain(self)
    monkeypatch.setattr(solvers.BlockSNES, "_residual", recorded)
    monkeypatch.setattr(solvers.BlockSNES, "_plain_newton", counted)
    model = build()
    stepper = TimeStepper(model.problem, solver_options=options)
    outcome = run(stepper)
    x = np.concatenate(model.mesh.comm.allgather(model.f["displacement"].x.array))
    monkeypatch.undo()
    return norms, x, stepper.stats.newton_iterations, bool(own), outcome


def _falling_rod():
    model = RodModel(RodParameters(length=1.0, A=(0.3, 0.4, 0.2), B=(1e2, 1e2, 3e2),
                                   density=2.0, section_inertia=1e-3), n_cells=6,
                     distributed_loads=[DistributedLoad("force", (-5.0, 0.0, 1.0))])
    model.set_initial_state()
    return model


def _rolled_rod():
    model = RodModel(RodParameters(length=1.0, A=(2.0, 2.0, 1.0), B=(1e3, 1e3, 1e3)),
                     n_cells=8, model="hyperelastic", end_loads=[EndLoad(
                         "couple", (4 * np.pi, 0.0, 0.0), loads.ramp(1.0, 1.0),
                         follower=True)])
    model.set_initial_state()
    return model


def _poisoned_rod():
    """The falling rod with a non-finite displacement on every rank (an owned entry: the
    first), so that every residual norm is NaN."""
    model = _falling_rod()
    model.f["displacement"].x.array[0] = np.nan
    return model


def _failure(stepper):
    """The message of a step that fails (no step cuts), or None."""
    from dolfin_rod import IntegrationError
    stepper.max_cuts = 0
    try:
        stepper.run(0.0, 0.05, 0.05)
    except IntegrationError as err:
        return str(err)
    return None


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["dynamic", "quasi-static", "max_it", "linear solve",
                                  "non-finite"])
def test_own_newton_loop_is_snes_newtonls_iterate_for_iterate(monkeypatch, case):
    """BlockSNES runs Newton itself (_plain_newton) with the default options and any that
    set only PLAIN_NEWTON's SNES options; with another SNES option SNESSolve runs (newtonls,
    basic line search).  The reference is SNESSolve: every iterate's residual norm, the
    final state and the iteration counts are the same bit for bit (the same operations in
    the same order), on a dynamic rod (generalized-alpha on rotation vectors: SNES's KSP
    is PETSc's LU serially, block-Jacobi GMRES on 2 ranks) and a quasi-static one rolled
    up in 4 load steps (backward Euler); a solve that fails fails the same way, with the
    same reason (snes_max_it 1: DIVERGED_MAX_IT; a linear solve stopped after one GMRES
    iteration without a preconditioner: DIVERGED_LINEAR_SOLVE; a NaN in the state:
    DIVERGED_FNORM_NAN, PETSc 3.23+ DIVERGED_FUNCTION_NANORINF)."""
    build, extra, run = {
        "dynamic": (_falling_rod, {}, lambda st: st.run(0.0, 0.2, 0.02)),
        "quasi-static": (_rolled_rod, {}, lambda st: st.run(0.0, 1.0, 0.25)),
        "max_it": (_falling_rod, {"snes_max_it": 1, "snes_rtol": 1e-14}, _failure),
        "linear solve": (_falling_rod, {"ksp_type": "gmres", "ksp_max_it": 1,
                                        "pc_type": "none"}, _failure),
        "non-finite": (_poisoned_rod, {}, _failure)}[case]
    own = _recorded_solves(monkeypatch, build, extra, run)
    snes = _recorded_solves(monkeypatch, build, {**extra, **THROUGH_SNES}, run)
    assert own[3] and not snes[3]
    assert np.array_equal(own[0], snes[0], equal_nan=True) and own[0]
    assert np.array_equal(own[1], snes[1], equal_nan=True) and own[2] == snes[2]
    assert own[4] == snes[4]
    if case == "dynamic":
        assert np.abs(own[1]).max() > 1e-3 and len(own[0]) > 20     # the rod moved
    elif case == "quasi-static":
        assert np.abs(own[1]).max() > 0.5           # rolled up: the tip moved by ~L
    else:
        reason = {"max_it": "DIVERGED_MAX_IT", "linear solve": "DIVERGED_LINEAR_SOLVE",
                  "non-finite": "DIVERGED_F"}[case]
        assert reason in own[4], own[4]

