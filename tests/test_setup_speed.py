"""The set-up shortcuts of issue 30 (target 1) give the numbers of the general path.

A model's structure as data (rod/structure.py) stands for its residual's UFL
signatures, which select the compiled kernels: two models with equal texts must have
equal signatures (checked here across material numbers and cell counts, and on every
bundled rod scene at two cell counts), and a term more or less must change the text.

The reference strains of a straight rod along e_3 are written directly (u_ref = 0,
v_ref = e_3; rod/initial_state.py) instead of interpolating the compiled strain
expressions: here they are compared, bit for bit, with those expressions evaluated on
the same state, for each kind of rotation unknown and each model that computes its
strains differently (rotation vectors, quaternions, an unshearable rod, the uniform
variant).  Speed itself is measured by benchmarks/setup_cost.py.
"""

from __future__ import annotations

import dolfinx.fem as fem
import numpy as np
import pytest
import ufl
from mpi4py import MPI

import re
from pathlib import Path
from unittest import mock

from dolfin_rod.fem import compat, form_cache
from dolfin_rod.rod import DistributedLoad, EndLoad, RodModel, RodParameters, residual
from dolfin_rod.run import choose_model
from dolfin_rod.scenes import load_scene, parse_scene
from dolfin_rod.scenes.builders import build

SCENES = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.toml"))
ROD_SCENES = [p for p in SCENES if choose_model(load_scene(p), 1).model == "rod"]

CASES = {
    "dynamic, rotation vectors": dict(
        params=dict(density=2.0, section_inertia=1e-3), model="hyperelastic"),
    "quasi-static creep, quaternions": dict(
        params=dict(A_d=(1.0, 1.0, 1.0), B_d=(10.0, 10.0, 10.0), M_d=(1.0, 1.0, 1.0),
                    N_d=(1.0, 1.0, 1.0)), model="evolving", rotations="quaternion"),
    "unshearable, uniform variant": dict(
        params=dict(A_d=(1.0, 1.0, 1.0), B_d=(10.0, 10.0, 10.0), M_d=(1.0, 1.0, 1.0),
                    N_d=(1.0, 1.0, 1.0)), model="evolving", variant="uniform",
        constraints="unshearable"),
}


def compiled_strains(model: RodModel) -> tuple[np.ndarray, np.ndarray]:
    """u, v of the current state at the reference strains' points, by fem.Expression."""
    out = []
    for expr, field in zip((model.u, model.v), model.reference):
        g = fem.Function(field.function_space)
        g.interpolate(fem.Expression(expr, compat.interpolation_points(g.function_space)))
        out.append(g.x.array.copy())
    return out[0], out[1]


VALUES = (dict(A=(2.0, 3.0, 4.0), B=(50.0, 60.0, 70.0)),
          dict(A=(2.5, 0.5, 1.0), B=(40.0, 65.0, 90.0)))


def make(case: str, values: dict = VALUES[0], n_cells: int = 4, loads=None,
         comm: MPI.Comm = MPI.COMM_WORLD, **changes) -> RodModel:
    """The model of a case with material numbers ``values`` and ``changes``."""
    spec = CASES[case]
    params = RodParameters(**values, **{**spec["params"], **changes})
    loads = loads or dict(distributed_loads=[DistributedLoad("force", (1.0, 0.0, 0.0))])
    return RodModel(params, n_cells=n_cells, model=spec["model"],
                    variant=spec.get("variant", "local"), constraints=spec.get("constraints"),
                    rotations=spec.get("rotations", "auto"), comm=comm, **loads)


def signatures(model) -> str:
    return form_cache.structure_key(model.problem.residual)


@pytest.mark.mpi
@pytest.mark.parametrize("case", CASES)
def test_straight_reference_strains_equal_the_compiled_strains(case):
    """Bit-identical: u_ref = 0 and v_ref = e_3 are what the strain kernels give for a
    straight rod (q = 1, x = 0 at every node), so every later number is unchanged."""
    model = make(case)
    model.set_initial_state()
    u, v = compiled_strains(model)
    u_ref, v_ref = (f.x.array for f in model.reference)
    assert np.array_equal(u_ref, u) and np.array_equal(v_ref, v)
    assert np.array_equal(v.reshape(-1, 3), np.tile([0.0, 0.0, 1.0], (len(v) // 3, 1)))


def test_a_curved_rod_keeps_the_compiled_strains():
    """A helix (reference curvature) is not straight: its reference strains are the
    compiled ones, and they differ from (0, e_3)."""
    params = RodParameters(A=(2.0, 3.0, 4.0), B=(50.0, 60.0, 70.0),
                           reference_curvature=(0.0, 1.0, 0.5))
    model = RodModel(params, n_cells=4, model="hyperelastic", comm=MPI.COMM_WORLD)
    model.set_initial_state()
    u, v = compiled_strains(model)
    assert np.array_equal(model.reference[0].x.array, u)
    assert np.abs(u.reshape(-1, 3)[:, 1] - 1.0).max() < 0.05   # discrete curvature ~ u0


@pytest.mark.mpi
@pytest.mark.parametrize("case", CASES)
def test_models_of_one_structure_have_one_text_and_one_signature(case):
    """Other material numbers and another cell count: the same structure text, and the
    same UFL signatures (so the same kernels), which the text's key then stands for."""
    first, second = (make(case, values, n) for values, n in zip(VALUES, (4, 6)))
    assert first.problem.structure is not None
    assert first.problem.structure == second.problem.structure
    assert signatures(first) == signatures(second)
    via_text = [form_cache.structure_key(m.problem.residual, "step",
                                         structure=m.problem.structure) for m in (first, second)]
    assert via_text[0] == via_text[1] == form_cache.structure_key(second.problem.residual, "step")


@pytest.mark.parametrize("change", ["drag", "follower load", "end couple", "end slide"])
def test_a_term_more_is_another_structure(change):
    """Each change adds or alters a residual term: the text and the signatures differ."""
    case = "dynamic, rotation vectors"
    changed = {
        "drag": lambda: make(case, drag=0.3),
        "follower load": lambda: make(case, loads=dict(distributed_loads=[
            DistributedLoad("force", (1.0, 0.0, 0.0), follower=True)])),
        "end couple": lambda: make(case, loads=dict(end_loads=[
            EndLoad("couple", (0.0, 0.0, 1.0))], distributed_loads=[
            DistributedLoad("force", (1.0, 0.0, 0.0))])),
        "end slide": lambda: make(case, loads=dict(
            distributed_loads=[DistributedLoad("force", (1.0, 0.0, 0.0))],
            start="clamped", end="pinned", end_slide={"end": (0.0, 0.0, 1.0)})),
    }[change]()
    base = make(case)
    assert changed.problem.structure not in (None, base.problem.structure)
    if change != "end slide":       # a Dirichlet condition: same forms, other key
        assert signatures(changed) != signatures(base)


def user_energy(u_d, v_d, u, v):
    """A user's energy function (it could read numbers that change between models)."""
    return 2.0 * ufl.inner(u - u_d, u - u_d) + 50.0 * ufl.inner(v - v_d, v - v_d)


@pytest.mark.parametrize("given", ["stiffness profile", "user energy"])
def test_a_function_not_of_this_package_gives_no_text(given):
    """A stiffness profile A(s), or a user's energy, is UFL holding its own numbers: no
    text (the signatures decide); dolfin_rod.dna:psi has one (the bundled DNA scenes)."""
    values = {"stiffness profile": dict(A=lambda s: (2.0 + s, 3.0, 4.0), B=(50.0, 60.0, 70.0)),
              "user energy": dict(VALUES[0], energy=user_energy)}[given]
    model = make("dynamic, rotation vectors", values)
    assert model.problem.structure is None


def doubled_cells(path: Path):
    """The scene ``path`` with every n_cells of its text doubled: the scene's and each
    rod's of [[rods]] (an override of geometry.n_cells does not reach a rod that gives
    its own; it is refused, tests/test_faults.py)."""
    text = re.sub(r"(\bn_cells\s*=\s*)(\d+)", lambda m: f"{m[1]}{2 * int(m[2])}",
                  path.read_text())
    return parse_scene(text, str(path), path.stem, files=str(path.parent))


def with_cells_doubled(text: str) -> str:
    """A structure text with its rods' cell counts doubled: a system's layout, the
    "|(n_1,n_2,...)|" after the rotation unknowns (a single rod's text has none: "||")."""
    return re.sub(r"\|\((\d+(?:,\d+)*)\)\|", lambda m: "|({})|".format(
        ",".join(str(2 * int(n)) for n in m[1].split(","))), text, count=1)


@pytest.mark.parametrize("path", ROD_SCENES, ids=lambda p: p.stem)
def test_bundled_rod_scenes_at_two_cell_counts(path):
    """Every bundled rod scene (systems too) built at two cell counts: equal texts (a
    system's: but for its rods' cell counts, doubled) with equal signatures (a scene whose energy is a function has no text; a contact law's
    default stiffness depends on the cell size, a number in the text: other texts, unless
    the scene gives it)."""
    # doubled: a polyline's corners (bent_frame: split into rigidly joined pieces of
    # cells in proportion to their lengths, rod/kinks.py) give the same pieces, doubled
    scenes = [load_scene(path), doubled_cells(path)]
    models = [build(scene, "rod").model for scene in scenes]
    texts = [m.problem.structure for m in models]
    contact = models[0].contact or models[0].segment_contact
    same = texts[0] is not None and with_cells_doubled(texts[0]) == texts[1]
    assert same or texts[0] is texts[1] is None or contact
    if same:
        assert signatures(models[0]) == signatures(models[1])


@pytest.mark.mpi
def test_a_gathered_residual_is_the_form_of_its_sum():
    """A block residual gathered term by term (fem/gathered_form.GatheredForm: its
    integrals kept, one ufl.Form made at the end) is the Form that UFL's own + and - give
    (the reference): equal integrals, so the same signature, the key of the compiled
    kernels, across cell, facet and vertex integrals with several quadrature rules; an
    integrand added with its measure (``integrate``) is the integral of integrand * dx."""
    import dolfinx.mesh

    from dolfin_rod.fem.gathered_form import GatheredForm, as_form
    mesh = dolfinx.mesh.create_unit_interval(MPI.COMM_WORLD, 4)
    f = fem.Function(fem.functionspace(mesh, ("Lagrange", 1, (3,))))
    v = ufl.TestFunction(f.function_space)
    c = fem.Constant(mesh, 2.0)
    dx_2 = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 2})
    dx_v = ufl.Measure("dx", domain=mesh, metadata={"quadrature_rule": "vertex",
                                                      "quadrature_degree": 1})
    first = ufl.inner(f.dx(0), v.dx(0))
    terms = [first * ufl.dx, c * ufl.inner(f, v) * dx_2,
             ufl.inner(f, f) * v[0] * ufl.ds, ufl.inner(f, v) * dx_v, c * v[2] * ufl.dx]
    chain, gathered = terms[0], GatheredForm()
    gathered.integrate(first, ufl.dx)                  # terms[0] without its Form
    for k, term in enumerate(terms[1:]):
        if k % 2:
            chain = chain - term
            gathered -= term
        else:
            chain = chain + term
            gathered += term
    form = as_form(gathered)
    assert form == chain
    assert form.signature() == chain.signature()
    assert as_form(chain) is chain


@pytest.mark.mpi
@pytest.mark.parametrize("case", list(CASES))
def test_a_second_models_diagnostics_and_reactions_are_its_own(case, monkeypatch):
    """The kernels of the diagnostics (fem/fe_model.FormSums) and of the reactions
    (compiled_near_nodes: the residual on the cells at the supported ends) are compiled
    once per structure and bound to each later model's data and cells: a second model of
    the structure, with other material numbers and another cell count, gives after two
    steps the energies, powers and reactions that it gives with every form compiled
    afresh (the reference: the form cache bypassed).  Bitwise in serial; the tolerance
    leaves room for a parallel solve's other rounding (1e-17 measured in
    test_rotation_vector)."""
    from dolfin_rod import TimeStepper

    def diagnostics(values: dict, n_cells: int) -> dict:
        model = make(case, values, n_cells=n_cells)
        model.set_initial_state()
        TimeStepper(model.problem).run(0.0, 0.02, 0.01)
        return model.diagnostics(0.02)

    diagnostics(VALUES[0], 4)                        # the structure's kernels, remembered
    binds, bind = [], form_cache.bind

    def counted(*args):
        binds.append(args)
        return bind(*args)
    monkeypatch.setattr(form_cache, "bind", counted)
    bound = diagnostics(VALUES[1], 6)
    assert len(binds) >= 3          # the step kernels, the diagnostics, a reaction block
    monkeypatch.setattr(form_cache, "lookup", lambda *args, **kwargs: None)
    fresh = diagnostics(VALUES[1], 6)
    assert bound.keys() == fresh.keys() and "reaction_force_start_x" in fresh
    size = max(abs(v) for v in fresh.values())
    assert max(abs(bound[k] - fresh[k]) for k in fresh) <= 1e-13 * size
    assert abs(fresh["reaction_force_start_x"]) > 1e-3 * size     # a load reacted


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["dynamic, rotation vectors", "quasi-static creep, quaternions"])
def test_a_second_model_makes_its_residual_only_when_read(case):
    """A second model of a structure (other material numbers, another cell count) binds
    the cached kernels and steps without making its residual's Forms
    (fem/gathered_form.LazyForms: the kernels' data are taken from the residual's terms);
    read after the steps, its residual has the signature of the first model's and exactly
    the Functions and Constants the kernels were bound to."""
    from dolfin_rod import TimeStepper
    from dolfin_rod.fem.gathered_form import LazyForms

    first = make(case, VALUES[0], n_cells=4)
    first.set_initial_state()
    TimeStepper(first.problem).run(0.0, 0.02, 0.01)
    with mock.patch.object(residual, "internal_forces",
                           wraps=residual.internal_forces) as terms_made:
        second = make(case, VALUES[1], n_cells=6)
        second.set_initial_state()
        TimeStepper(second.problem).run(0.0, 0.02, 0.01)
        assert terms_made.call_count == 0      # nor its terms (their data: by role)
        lazy = second.problem.residual
        assert isinstance(lazy, LazyForms) and not lazy.made
        assert second.m is not None and terms_made.call_count == 1     # made when read
    bound = form_cache.registry(lazy)
    made = list(lazy)
    assert lazy.made
    assert form_cache.registry(made) == bound
    assert signatures(second) == signatures(first)


@pytest.mark.mpi
def test_models_of_one_layout_share_their_mesh_and_spaces():
    """fem/shared_mesh.py: a second model of the same layout (other material numbers)
    takes the first's mesh, block spaces and its stepper's mixed space, with Functions
    of its own; another cell count has a mesh of its own."""
    from dolfin_rod import TimeStepper

    case = "dynamic, rotation vectors"
    first, second = (make(case, values, n_cells=4) for values in VALUES)
    other = make(case, VALUES[0], n_cells=6)
    assert second.mesh is first.mesh and other.mesh is not first.mesh
    for name in first.names:
        assert second.f[name].function_space is first.f[name].function_space
        assert second.f[name] is not first.f[name]
    spaces = []
    for model in (first, second):
        model.set_initial_state()
        stepper = TimeStepper(model.problem)
        stepper.compile()
        spaces.append(stepper.integrator.solver.system.W)
    assert spaces[0] is spaces[1]


@pytest.mark.mpi
def test_a_second_model_copies_the_cell_midpoints():
    """rod/rotation_vector.py: a second model of a layout takes the cell midpoints s of
    the first (no interpolation of its own); they are, cell for cell (ghosts too), the
    means of the cells' two vertex coordinates, and a Function of the second model."""
    case = "dynamic, rotation vectors"
    first = make(case, VALUES[0], n_cells=5)
    with mock.patch.object(fem.Function, "interpolate") as interpolate:
        second = make(case, VALUES[1], n_cells=5)
        assert interpolate.call_count == 0
    mesh = second.mesh
    cells = mesh.topology.index_map(1)
    vertices = compat.geometry_dofmap(mesh)[:cells.size_local + cells.num_ghosts]
    s = mesh.geometry.x[:, 0]
    dofs = second.unknowns.chart.s_mid.function_space.dofmap.list[:, 0]
    expected = np.empty(len(dofs))
    expected[dofs] = 0.5 * (s[vertices[:, 0]] + s[vertices[:, 1]])
    for model in (first, second):
        assert np.array_equal(model.unknowns.chart.s_mid.x.array, expected)
    assert second.unknowns.chart.s_mid is not first.unknowns.chart.s_mid


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="signals one process")
def test_an_interrupt_during_a_compile_waits_for_its_end():
    """FFCx cleans up a failed compile after an Exception only: a KeyboardInterrupt in it
    left a half-made module that every later run waited for and failed on.  Held: the
    block runs to its end, then the caller's own handler gets the signal."""
    import os
    import signal
    finished = []
    with pytest.raises(KeyboardInterrupt):
        with form_cache.interrupts_held():
            os.kill(os.getpid(), signal.SIGINT)
            finished.append(sum(range(10**5)))     # Python code after the signal
    assert finished == [sum(range(10**5))]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.mpi
def test_a_second_stepper_duplicates_the_first_ones_matrix_and_vectors():
    """fem/assembly.py: a second model of a structure and layout (other material numbers)
    makes its step solver's vectors and Jacobian without DOLFINx's create_vector and
    create_matrix (duplicates of the first system's, its matrix once assembled), and
    reads neither its rotation's UFL (rotation_ufl); its assembled Jacobian is, entry for
    entry, the one DOLFINx assembles into a matrix of its own sparsity pattern."""
    import dolfinx.fem.petsc as fem_petsc
    from dolfin_rod import TimeStepper

    case = "dynamic, rotation vectors"
    first = make(case, VALUES[0], n_cells=4)
    first.set_initial_state()
    TimeStepper(first.problem).run(0.0, 0.02, 0.01)
    with mock.patch.object(fem_petsc, "create_matrix", wraps=fem_petsc.create_matrix) \
            as matrices, mock.patch.object(compat, "vector", wraps=compat.vector) as vectors:
        second = make(case, VALUES[1], n_cells=4)
        second.set_initial_state()
        stepper = TimeStepper(second.problem)
        stepper.run(0.0, 0.02, 0.01)
        assert matrices.call_count == 0 and vectors.call_count == 0
    assert "_rotation_expressions" not in vars(second.unknowns)
    assert "q" not in vars(second.unknowns.chart)
    system = stepper.integrator.solver.system
    reference = fem_petsc.create_matrix(system.J[0])
    system.jacobian(reference)
    system.jacobian(system.A)
    for ours, theirs in zip(system.A.getValuesCSR(), reference.getValuesCSR()):
        assert np.array_equal(ours, theirs)


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["dynamic, rotation vectors", "quasi-static creep, quaternions"])
def test_kernels_remembered_on_one_rank_only_are_compiled_on_every_rank(case):
    """A model on rank 0's own communicator (MPI.COMM_SELF, as a test or a user's script
    may build) remembers its step kernels on rank 0 alone; a model of the same structure
    on every rank then finds them on rank 0 only.  form_cache.lookup agrees over the
    model's ranks, so every rank compiles: a hit on rank 0 against a miss on rank 1 left
    rank 1 in DOLFINx's collective JIT and rank 0 past it (the MPI suite hung at
    tests/test_snake.py).  Both models' steps give the serial run's tip to 1e-12 (a
    parallel solve's other rounding: 1e-17 measured, test_rotation_vector)."""
    from dolfin_rod import TimeStepper

    def tip(comm: MPI.Comm) -> tuple[np.ndarray, str]:
        model = make(case, comm=comm)
        model.set_initial_state()
        stepper = TimeStepper(model.problem)
        stepper.run(0.0, 0.02, 0.01)
        d = model.diagnostics(0.02)
        return np.array([d[f"tip_position_{c}"] for c in "xyz"]), stepper.structure_key

    world = MPI.COMM_WORLD
    form_cache.clear(disk=False)
    alone = tip(MPI.COMM_SELF) if world.rank == 0 else None
    key = world.bcast(alone[1] if world.rank == 0 else None)
    known = world.allgather(form_cache.lookup(key, MPI.COMM_SELF) is not None)
    assert known == [True] + [False] * (world.size - 1)     # the situation of the hang
    together = tip(world)
    assert together[1] == key                   # the same kernels
    if world.rank == 0:
        assert np.allclose(together[0], alone[0], rtol=0, atol=1e-12)


@pytest.mark.mpi
def test_a_second_model_with_a_real_space_unknown_binds_its_step_blocks(monkeypatch):
    """The uniform variant's natural strains are real-space unknowns: its step system is
    assembled in blocks (fem/assembly.BlockedSystem).  A second model of its structure
    (other material numbers, another cell count) binds the first one's compiled blocks:
    it takes no derivative of its step residual (jacobian_blocks, most of such a
    stepper's set-up), and its state after two steps is the one it reaches with every
    form compiled afresh (the form cache bypassed): bitwise in serial, to 1e-13 on two
    ranks (a parallel solve's other rounding, as above)."""
    from dolfin_rod import TimeStepper
    from dolfin_rod.fem import assembly

    def state(values: dict, n_cells: int) -> np.ndarray:
        model = make("unshearable, uniform variant", values, n_cells=n_cells)
        assert not assembly.monolithic_layout(model.problem.fields)
        model.set_initial_state()
        TimeStepper(model.problem).run(0.0, 0.02, 0.01)
        return np.concatenate([f.x.array for f in model.problem.fields])

    state(VALUES[0], 4)                              # the structure's blocks, remembered
    derivatives = mock.patch.object(assembly, "jacobian_blocks",
                                    wraps=assembly.jacobian_blocks)
    with derivatives as bound_calls:
        bound = state(VALUES[1], 6)
    monkeypatch.setattr(form_cache, "lookup", lambda *args, **kwargs: None)
    with derivatives as fresh_calls:
        fresh = state(VALUES[1], 6)
    assert bound_calls.call_count == 0 < fresh_calls.call_count
    if MPI.COMM_WORLD.size == 1:
        assert np.array_equal(bound, fresh)
    assert np.max(np.abs(bound - fresh)) <= 1e-13 * np.max(np.abs(fresh))


def test_a_cached_kernel_is_found_without_listing_ffcx_s_cache(tmp_path, monkeypatch):
    """FFCx 0.9-0.11 list their whole cache directory at every cache hit (FFCx issue
    886); the package's compiles find the module by its path: a form compiled into a
    fresh cache, then compiled again, loads the same module with no listing of that
    directory, and a kernel whose compile never finished (.c without .c.cached) still
    times out with FFCx's message naming the .c file (jit_form's stale-lock removal reads
    it)."""
    import posix                        # importlib's FileFinder lists through posix

    import dolfinx.mesh
    from ffcx.codegeneration import jit
    mesh = dolfinx.mesh.create_unit_interval(MPI.COMM_SELF, 2)
    form = fem.Constant(mesh, 1.7) * ufl.dx(domain=mesh)
    options = {"cache_dir": str(tmp_path), "timeout": 1}
    with form_cache.modules_found_by_path():
        first = fem.form(form, jit_options=options)             # compiles
        listed = []
        real_listdir = posix.listdir
        monkeypatch.setattr(posix, "listdir", lambda path=".": listed.append(str(path))
                            or real_listdir(path))
        again = fem.form(form, jit_options=options)             # a cache hit
        monkeypatch.undo()
    assert str(tmp_path) not in listed, listed
    assert jit.get_cached_module is not form_cache.cached_module     # restored
    assert fem.assemble_scalar(again) == pytest.approx(fem.assemble_scalar(first))
    assert fem.assemble_scalar(again) == pytest.approx(1.7, rel=1e-14)
    (tmp_path / "libffcx_forms_unfinished.c").write_text("")
    with pytest.raises(TimeoutError, match=r"remove .*libffcx_forms_unfinished\.c\)"):
        form_cache.cached_module("libffcx_forms_unfinished", [], tmp_path, 1)
