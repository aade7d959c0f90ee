"""Scene -> running model: a registry of builders, one per model name.

Every built model is a :class:`Simulation`: ``start()`` puts it at t0 (returns the end
torsion impulse of an idealised step, eq. ``stressrelax``), ``advance(t, t_next)``
integrates one output interval, ``diagnostics(t)`` gives the scalars of
``TorsionModel.diagnostics`` (same keys for every model), ``fields`` the FE functions
to write (none for the ODE), ``state()``/``restore(...)`` what a checkpoint needs.

The ODE model of quasi-static homogeneous torsion (eqs. ``twist``, ``nattwist``) is
torsion/ode.py.  The integrator of an FE model is picked in integrators/choice.py.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Protocol

import numpy as np

from ..checks import ENDS, NEWTON_ATOL
from ..rod.ring import MECHANISM
from ..rod.start import curve
from .contact import (contact_law, contact_solver_options, obstacles, segment_pairs,
                      touching)
from .rules import START_KEYS, adaptive_stepper, rod_rotations
from .scene import Scene, SceneError
from .values import Coefficient

CONTACT_SCHEME = "generalized_alpha:0.0"   # rho_inf = 0: a barrier's impacts (docs/contact.md)
__all__ = ["Simulation", "MODELS", "register_model", "build", "FESimulation"]


class Simulation(Protocol):
    name: str
    fields: list
    comm: object

    def start(self) -> float: ...
    def advance(self, t: float, t_next: float) -> None: ...
    def diagnostics(self, t: float) -> dict[str, float]: ...
    def state(self) -> dict: ...
    def restore(self, state: dict) -> None: ...


MODELS: dict[str, Callable[[Scene], Simulation]] = {}


def register_model(name: str):
    """Decorator: ``@register_model("rod")`` makes ``build`` dispatch the name to it."""
    def wrap(builder):
        MODELS[name] = builder
        return builder
    return wrap


def build(scene: Scene, model: str, comm=None) -> Simulation:
    if model not in MODELS:
        raise scene.error("scene.model", f"no builder registered for model {model!r} "
                                         f"(registered: {', '.join(MODELS)})")
    try:
        return MODELS[model](scene, comm)
    except SceneError:
        raise
    except (ValueError, TypeError) as err:   # a model's own validation (architecture.md)
        raise scene.error("scene.model", f"the {model!r} model rejected the scene: {err}") from err


@register_model("ode")
def build_ode(scene: Scene, comm=None):
    """The homogeneous torsion ODE (torsion/ode.py) of a scene."""
    from ..torsion.ode import EndCondition, OdeTime, OdeTorsion
    mat, tim = scene["material"], scene["time"]
    rotation = scene["boundary"]["end"] == "rotation"
    spec = scene["boundary"]["end_rotation"] if rotation else scene["loads"]["end_torsion"]
    end = EndCondition(rotation) if spec is None else EndCondition(
        rotation, spec.build(), spec.value if spec.jumps_at_start else None,
        spec.breakpoints())
    atol = NEWTON_ATOL if tim["atol"] is None else tim["atol"]    # (the twist, in rad)
    time = OdeTime(tim["t_end"], tim["dt"], tim["rtol"], atol, tim["ode_solution"],
                   tim["scheme"])
    return OdeTorsion(*(mat[k].constant for k in ("alpha", "alpha_d", "mu", "mu_d")), end,
                      time, scene["initial"]["natural_twist"] or 0.0, comm)


# --- FE models: torsion PDE and the 3-D rod ---------------------------------------------------


class FESimulation:
    """A model with ``.problem`` advanced by TimeStepper (or the PETSc TS integrator)."""

    def __init__(self, name: str, model, scene: Scene, initial_state: Callable[[], float],
                 started: bool = False):
        """``started``: ``initial_state`` already ran (a scene with contact checks its start
        for overlaps at build): the first ``start()`` keeps that state, without a second
        start (and a second settle)."""
        from ..fem.problem import SecondOrderProblem
        from ..integrators.choice import choose_integrator
        tim = scene["time"]
        self.name, self.model, self.scene = name, model, scene
        self.problem = model.problem
        self.comm = self.problem.comm
        self.fields = list(self.problem.fields)
        self._initial_state = initial_state
        self._started = started
        self.continued = False      # the integrator continues a saved history (restart)
        lie = isinstance(self.problem, SecondOrderProblem)   # rotation vectors (rules.py)
        options = solver_options(scene, second_order=lie)
        if tim["integrator"] == "ts":
            self.stepper, self.ts = None, choose_integrator(
                self._ts_problem(), solver_options=options, ts_type=self._ts_type(),
                adaptive=tim["adaptive"], rtol=tim["ts_rtol"], atol=tim["ts_atol"])
            self.stability, self.branches = self._stability_monitor(), None
            self.continuation = None
            return
        # not given, a rod with rotation vectors takes its integrator's default scheme
        # (with obstacles: rho_inf = 0, docs/contact.md)
        scheme = tim["scheme"]
        if lie and "scheme" not in scene.given["time"]:
            scheme = CONTACT_SCHEME if touching(scene) and model.dynamic else None
        tolerance = tim["tolerance"] if adaptive_stepper(scene) else None
        self.stepper, self.ts = choose_integrator(
            self.problem, scheme, options, max_step_cuts=tim["max_step_cuts"],
            predictor=tim["predictor"], tolerance=tolerance), None
        self.stability = self._stability_monitor()
        self.continuation = self._continuation()
        self.branches = None if self.continuation else self._branch_switching()

    def _continuation(self):
        """Arc-length continuation (analysis/continuation.py) in place of the time steps,
        if the scene asks for it."""
        con = self.scene["continuation"]
        if con["method"] != "arc_length":
            return None
        from ..analysis.continuation import ArcLength
        return ArcLength(self.model, con["arc_length"], con["load_scale"],
                         max_steps=con["max_steps"])

    def _branch_switching(self):
        """Branch switching at bifurcations (analysis/branches.py): quasi-static rods
        without constraints whose stability is checked, unless stability.at_bifurcation
        = "stay"; not with segment contact (the descent's steps have no check that
        segments pass through each other: the count is reported, the path stays), nor
        with Kelvin-Voigt viscosity or drag (the positions move at a viscous rate: the
        rod creeps away from an unstable equilibrium, it does not jump; the count is
        reported, the path stays)."""
        if self.stability is None or self.scene["stability"]["at_bifurcation"] != "switch" \
                or segment_pairs(self.scene) or self.model.rate_dependent:
            return None
        from ..analysis.branches import BranchSwitching
        try:
            return BranchSwitching(self.stability)
        except ValueError:          # constraints (LowestEigenvalues)
            return None

    def _stability_monitor(self):
        """Quasi-static 3-D rods: the stability of each step's equilibrium
        (analysis/stability.py; segment contact's pairs included in K; a system with
        joints: K on the free dofs of the joints' constraint map, P^T K P)."""
        scene, model = self.scene, self.model
        if scene.is_rod_material and not model.dynamic and scene["stability"]["check"]:
            from ..analysis.stability import StabilityMonitor
            return StabilityMonitor(model, scene["stability"]["lowest_eigenvalue"],
                                    scene["stability"]["factorisation"] == "banded")
        return None

    def _ts_type(self) -> str:
        return self.scene["time"]["ts_type"] or ts_type(self.scene)

    def _ts_problem(self):
        """The problem PETSc TS advances: TSALPHA2 needs the second-order form."""
        if not self._ts_type().startswith("alpha2"):
            return self.problem
        if not hasattr(self.model, "second_order_problem") or not self.model.dynamic:
            raise self.scene.error("time.ts_type", "alpha2 (TSALPHA2) needs a second-order "
                                                   "problem: dynamic torsion (nu > 0)")
        return self.model.second_order_problem()

    def run_all(self, t0: float, t_end: float, dt: float, on_step: Callable[[float], None]):
        """PETSc TS over the whole run (its multistep history must not restart at every
        output time), or the arc-length continuation from t0 until t_end; ``on_step(t)``
        after each accepted step."""
        if self.continuation is not None:
            self.continuation.run(t0, t_end, after_step=on_step)
            return
        self.ts.run(t0, t_end, dt, observer=lambda t, _: on_step(t) if t > t0 else None)

    def start(self) -> float:
        if self._started:           # made at build (a rod's start returns no impulse)
            self._started = False
            return 0.0
        return float(self._initial_state() or 0.0)

    def begin(self, t0: float) -> None:
        """The integrator's start before the first row: the rotation-group integrator's
        consistent state at t0 (a quasi-static rod in equilibrium with its loads), unless
        it continues a saved history (``restart``)."""
        if self.ts is None and hasattr(self.stepper, "initial_accelerations") \
                and not self.continued:
            self.stepper.initial_accelerations(t0)

    def restart(self, state: dict | None) -> None:
        """After a saved state was read into the model (output/from_run.py): its ends held
        where the state has them (a rod's ``hold_ends``), and the integrator's history continued from
        the checkpoint's ``state``, its clock moved to t = 0, or (None) started afresh."""
        if hasattr(self.model, "hold_ends"):
            self.model.hold_ends()
        if state is not None:
            self.stepper.restore_state({**state, "end_time": 0.0})
        self.continued = state is not None

    def advance(self, t: float, t_next: float) -> None:
        self.stepper.run(t, t_next, t_next - t)
        if self.branches is not None:
            self.branches.check(t_next, t)

    def diagnostics(self, t: float) -> dict[str, float]:
        d = self.model.diagnostics(t)
        if self.stability is not None:
            checked = self.branches is not None and self.branches.checked_at == t
            d["negative_eigenvalues"] = float(self.stability.negative if checked
                                              else self.stability.check(t))
            if self.stability.lowest is not None:
                d["lowest_eigenvalue"] = self.stability.lowest
        return d

    def state(self) -> dict:
        """Functions a checkpoint stores (besides problem.fields): the integrator's and
        the model's, and their flags."""
        stepper = self.stepper.checkpoint_state()
        model = getattr(self.model, "checkpoint_state", dict)()
        return {**stepper, **model, "functions": {**stepper["functions"],
                                                  **model.get("functions", {})}}

    def restore(self, state: dict) -> None:
        self.stepper.restore_state(state)
        if hasattr(self.model, "restore_state"):
            self.model.restore_state(state)

    @property
    def stats(self):
        """Steps, Newton iterations and rejected steps of the integrator that ran."""
        return self.ts.stats if self.ts is not None else self.stepper.stats

    def describe(self) -> str:
        if self.ts is not None:
            return f"PETSc TS ({self.ts.method})"
        return self.stepper.description


def solver_options(scene: Scene, second_order: bool = False) -> dict:
    """PETSc options of a scene: tolerances of [time] (rtol given only for a rod with
    rotation vectors, whose integrator has its own defaults, lie_alpha.default_options;
    atol given only: else the solvers scale it, solvers.ScaledAtol), the [solver]
    preset, its options."""
    from ..fem import solvers
    tim, sol = scene["time"], scene["solver"]
    preset = {"default": {}, "native_lu": solvers.NATIVE_LU,
              "jacobian_reuse": solvers.JACOBIAN_REUSE}[sol["preset"]]
    tolerances = {f"snes_{k}": tim[k] for k in ("rtol", "atol")
                  if k in scene.given["time"] or (k == "rtol" and not second_order)}
    return {**contact_solver_options(scene), **tolerances, **preset, **(sol["options"] or {})}


def ts_type(scene: Scene) -> str:
    """The PETSc TS type (integrators.ts) of a scheme name of integrators.schemes."""
    name = scene["time"]["scheme"]
    if name.startswith("generalized_alpha"):
        return "alpha" + name[len("generalized_alpha"):]
    mapping = {"bdf2": "bdf:2", "backward_euler": "backward_euler",
               "crank_nicolson": "crank_nicolson", "implicit_midpoint": "implicit_midpoint"}
    if name not in mapping:
        raise scene.error("time.scheme", f"{name} has no PETSc TS counterpart "
                                         f"(use one of {', '.join(mapping)}, generalized_alpha)")
    return mapping[name]


@register_model("torsion")
def build_torsion(scene: Scene, comm=None) -> FESimulation:
    from mpi4py import MPI

    from ..torsion.model import TorsionModel, TorsionParameters
    mat, geo, lds = scene["material"], scene["geometry"], scene["loads"]
    kwargs = {}
    couple = lds["distributed_couple"]
    if couple is not None:
        profile = couple.profile or Coefficient(constant=1.0)
        kwargs["couple"] = (lambda s, c=profile.constant: c + 0.0 * s) if profile.is_constant \
            else profile
        kwargs["couple_history"] = couple.build()
    params = TorsionParameters(**{k: mat[k].value() for k in ("alpha", "alpha_d", "mu", "mu_d",
                                                              "nu")}, **kwargs)
    if scene["boundary"]["end"] == "rotation":
        ends = {"end_rotation": scene["boundary"]["end_rotation"].build()}
    else:
        spec = lds["end_torsion"]
        ends = {"end_torsion": spec.build() if spec is not None else (lambda t: 0.0)}
    model = TorsionModel(params, n_cells=geo["n_cells"], variant=mat["variant"],
                         degree=geo["degree"], comm=comm or MPI.COMM_WORLD, **ends)
    return FESimulation("torsion", model, scene,
                        lambda: model.set_initial_state(scene["initial"]["natural_twist"] or 0.0))


@register_model("rod")
def build_rod(scene: Scene, comm=None) -> FESimulation:
    """The 3-D rod (dolfin_rod.rod.RodModel) with every scene key mapped to its API; a
    scene with [[rods]]: a RodSystem of its rods and joints (scenes/systems.py)."""
    from mpi4py import MPI
    from ..rod import RodModel, RodSystem

    mat = scene["material"]
    params = rod_parameters(scene)
    common = dict(model=mat["model"], variant=mat["variant"],
                  constraints=None if mat["constraints"] == "none" else mat["constraints"],
                  rotations=rod_rotations(scene), comm=comm or MPI.COMM_WORLD,
                  obstacles=obstacles(scene), contact=contact_law(scene, params))
    try:
        if scene.rods:
            rods, joints = rods_and_joints(scene)
            model = RodSystem(rods, joints, **common)
        else:
            model = RodModel(params, **rod_arguments(scene), **common)
    except ValueError as err:
        if str(err).startswith(MECHANISM):      # a clamped ring that turns: its weld's
            raise scene.error("boundary.start", str(err).removeprefix("start: ")) from err
        key = "material.energy" if str(err).startswith("energy") else "scene.model"
        raise scene.error(key, f"the 'rod' model rejected the scene: {err}") from err
    def initial_state():
        try:
            model.set_initial_state(**natural_strains(scene), start=rod_starts(scene)
                                    if scene.rods else starting_state(scene))
        except ValueError as err:   # a start the model refused (start.<field>: [initial]),
            field, colon, reason = str(err).partition(": ")   # e.g. no equilibrium found
            if not (colon and field.startswith("start.")):
                raise
            raise scene.error(f"initial.{field.removeprefix('start.')}", reason) from None
        warn_unstable_start(scene, model)

    if touching(scene):    # an obstacle or a segment cutting the rod at t = 0: refused
        # before the integrator is built; the start made here is the run's (started=True)
        from ..rod.obstacle_shapes import InitialOverlap
        from ..rod.segments import PairOverlap
        try:
            initial_state()
        except InitialOverlap as err:
            raise scene.error(f"obstacles[{err.obstacle}]", str(err)) from None
        except PairOverlap as err:
            raise scene.error(err.key, str(err)) from None
    return FESimulation("rod", model, scene, initial_state, started=touching(scene))


def warn_unstable_start(scene: Scene, model) -> None:
    """initial.equilibrium: a warning if the settled start is an unstable equilibrium
    (negative eigenvalues of its tangent stiffness, analysis/stability.py; conservative
    loads, whose stability the energy criterion decides).  A dynamic run stays on such a
    start while nothing perturbs it (a column settled straight above Euler's load stays
    straight to round-off), where any real rod leaves it."""
    entries = [rod.scene for rod in scene.rods] if scene.rods else [scene]
    if not any(e["initial"]["equilibrium"] for e in entries):
        return               # (before the import: the check's scipy, 0.13 s of CPU)
    from ..analysis.stability import StabilityMonitor, non_conservative
    if non_conservative(model):
        return
    negative = StabilityMonitor(model).count(0.0)      # settled with the loads at t = 0
    if negative:
        import warnings
        warnings.warn(f"initial.equilibrium: the settled start is an unstable equilibrium "
                      f"({negative} negative eigenvalue{'s' * (negative > 1)} of the "
                      "tangent stiffness, docs/stability.md): the run stays on it only "
                      "while nothing perturbs it, a real rod leaves it (a column above "
                      "its buckling load); start from a stable equilibrium, or add a "
                      "small perturbing load to follow the rod away from it")


def natural_strains(scene: Scene) -> dict:
    """The initial natural_curvature and natural_stretch of [initial]: a 3-vector or None;
    with [[rods]] {rod name: 3-vector} of the rods that give one (their own [initial] or
    the scene's)."""
    keys = ("natural_curvature", "natural_stretch")
    if not scene.rods:
        return {key: scene["initial"][key] for key in keys}
    return {key: {rod.name: rod.scene["initial"][key] for rod in scene.rods
                  if rod.scene["initial"][key] is not None} or None for key in keys}


def rod_starts(scene: Scene) -> dict | None:
    """{rod name: StartingState} of the rods of [[rods]] with [initial] start keys (each
    rod's own or the scene's), None if none has any."""
    starts = {rod.name: starting_state(rod.scene) for rod in scene.rods}
    return {name: start for name, start in starts.items() if start is not None} or None


def starting_state(scene: Scene):
    """The rod's StartingState of [initial] (rules.START_KEYS), None if none is given."""
    from ..rod import start
    ini = scene["initial"]
    if not any(k in scene.given["initial"] for k in START_KEYS):
        return None
    zero = (0.0, 0.0, 0.0)
    return start.StartingState(
        shape=curve(ini["shape"]), position=ini["position"] or zero,
        orientation=ini["orientation"] or zero, velocity=ini["velocity"] or zero,
        angular_velocity=ini["angular_velocity"] or zero,
        rotation_centre=ini["rotation_centre"], equilibrium=ini["equilibrium"],
        acceleration=ini["acceleration"])


def rod_arguments(scene: Scene) -> dict:
    """The arguments of one rod (RodModel, rod.Rod) besides its parameters: cells, ends,
    end motions, slides, turning clamps and springs, loads."""
    from ..rod import EndSpring
    boundary, motions = scene["boundary"], end_motions(scene)
    end_loads, distributed_loads = rod_loads(scene)
    geo = scene["geometry"]
    return dict(n_cells=geo["n_cells"], start=boundary["start"], end=boundary["end"],
                closed=geo["closed"], excess_link=geo["excess_link"],
                end_loads=end_loads, distributed_loads=distributed_loads,
                point_loads=rod_point_loads(scene),
                end_displacement=motions["displacement"], end_rotation=motions["rotation"],
                end_slide={end: axis for end in ENDS
                           if (axis := boundary[f"{end}_slide"]) is not None},
                end_springs={end: EndSpring(**spring) for end in ENDS
                             if (spring := boundary[f"{end}_spring"])},
                end_turn={end: axis for end in ENDS
                          if (axis := boundary[f"{end}_turn"]) is not None})


def end_motions(scene: Scene) -> dict:
    """{"displacement" | "rotation": {end: motion}} of the ends whose motion [boundary]
    prescribes (start_/end_displacement, start_/end_rotation)."""
    boundary = scene["boundary"]
    return {m: {end: spec.vector() for end in ENDS
                if (spec := boundary[f"{end}_{m}"]) is not None}
            for m in ("displacement", "rotation")}


def placed_rods(scene: Scene) -> list:
    """The rods of a scene with [[rods]] as rod/placement.PlacedRod: where each is at
    t = 0 and which ends are held, all the joints' checks read (rod/joint_points.py),
    without building RodParameters (whose materials load DOLFINx)."""
    from ..rod.placement import Geometry, PlacedRod
    rods = []
    for entry in scene.rods:
        geo, motions = entry.scene["geometry"], end_motions(entry.scene)
        boundary = entry.scene["boundary"]
        rods.append(PlacedRod(
            entry.name, Geometry(geo["length"], geo["reference_curvature"],
                                 geo["reference_stretch"], curve(geo["reference_shape"])),
            geo["n_cells"], (boundary["start"], boundary["end"]), motions["displacement"],
            motions["rotation"], entry.position, entry.orientation, geo["closed"],
            geo["excess_link"]))
    return rods


class CentreLine(NamedTuple):
    """A rod's nodes at t = 0 (``initial_centre_lines``): its name (None for the rod of
    a scene without [[rods]]), their rest arc lengths s on it and positions (n, 3), and
    the length of the piece they span (a rod split at its corners, rod/kinks.py, gives
    one per piece, as the model's layout has)."""

    rod: str | None
    s: np.ndarray
    points: np.ndarray
    length: float


class StartLines(NamedTuple):
    """The rods' centre lines at t = 0 (one per piece, in the model's order), the joints'
    nodes (piece, node, piece, node; the corners' rigid joints and each ring's weld, its
    nodes 0 and n, included: neighbours through them) and whether a
    start is settled in static equilibrium before t = 0 (initial.equilibrium: the points
    are where the settling starts, the rod's start known after that solve only)."""

    lines: list[CentreLine]
    joints: list[tuple[int, int, int, int]]
    settled: bool


def initial_centre_lines(scene: Scene) -> StartLines:
    """Where the nodes of every rod are at t = 0, as the model places them (its
    stress-free shape or [initial] start, placed; split at its corners as the model
    splits it), in numpy (no DOLFINx: ``dolfin-rod check``)."""
    from ..rod.joint_points import locate
    from ..rod.kinks import attach, split_placed, system_starts
    from ..rod.placement import Geometry, PlacedRod
    from ..rod.ring import closed_starts
    from ..rod.start import RodStarts
    if scene.rods:
        rods, starts = placed_rods(scene), rod_starts(scene) or {}
    else:
        geo, boundary = scene["geometry"], scene["boundary"]
        rods = [PlacedRod("rod", Geometry(geo["length"], geo["reference_curvature"],
                                          geo["reference_stretch"],
                                          curve(geo["reference_shape"])),
                          geo["n_cells"], (boundary["start"], boundary["end"]),
                          closed=geo["closed"], excess_link=geo["excess_link"])]
        start = starting_state(scene)
        starts = {} if start is None else {"rod": start}
    starts = closed_starts(rods, starts)      # a ring starts as its ring
    splits = [split_placed(rod) for rod in rods]
    pieces = [piece for split in splits for piece in split.rods]
    state = RodStarts(system_starts(starts, splits), pieces)
    lines = []
    for split in splits:
        name = split.rods[0].name if scene.rods else None
        for piece, offset in zip(split.rods, split.offsets):
            s = np.linspace(0.0, piece.params.length, piece.n_cells + 1)
            lines.append(CentreLine(name, s + offset, state.rod_state(piece, s)[0],
                                    piece.params.length))
    joints = locate(pieces, attach(scene_joints(scene) if scene.rods else [], splits))
    welds = [(k, 0, k, piece.n_cells) for k, piece in enumerate(pieces) if piece.closed]
    return StartLines(lines, joints + welds,
                      any(start.equilibrium for start in starts.values()))


def rods_and_joints(scene: Scene) -> tuple[list, list]:
    """The scene's rods (rod.Rod, from each rod's scene) and joints (rod.Joint) of a
    scene with [[rods]] (scenes/systems.py)."""
    from ..rod import Rod
    rods = [Rod(rod_parameters(entry.scene), **rod_arguments(entry.scene), name=entry.name,
                position=entry.position, orientation=entry.orientation)
            for entry in scene.rods]
    return rods, scene_joints(scene)


def scene_joints(scene: Scene) -> list:
    """The joints (rod.Joint) of a scene with [[rods]] (scenes/systems.py)."""
    from ..rod import Joint
    return [Joint(j.kind, j.rods, j.point, j.name, j.axis) for j in scene.joints]


def rod_parameters(scene: Scene):
    """RodParameters from [geometry] and [material] (tensors: 3x3 arrays or callables)."""
    from ..rod import RodParameters
    from .values import load_entry_point
    mat, geo = scene["material"], scene["geometry"]
    stiff, visc = mat["stiffness"], mat["viscosity"] or {}
    tensors = {k: t.value() for k, t in {**stiff, **visc}.items()
               if not (k in ("M", "N") and t.is_zero)}
    scalars = {k: mat[k].value() for k in ("density", "drag") if mat[k] is not None}
    energy = None
    if mat["energy"] is not None:
        energy = load_entry_point(mat["energy"], scene.folder)
    if mat["rotational_drag"] is not None:
        frame = "" if mat["rotational_drag_frame"] == "material" else "spatial_"
        tensors[frame + "rotational_drag"] = mat["rotational_drag"].value()
    return RodParameters(length=geo["length"], **tensors, density=scalars.get("density", 0.0),
                         drag=scalars.get("drag", 0.0),
                         section_inertia=mat["section_inertia"] or 0.0, energy=energy,
                         reference_curvature=geo["reference_curvature"],
                         reference_stretch=geo["reference_stretch"],
                         reference_shape=curve(geo["reference_shape"]))


def rod_loads(scene: Scene) -> tuple[list, list]:
    """EndLoads (start_/end_force/couple) and DistributedLoads (distributed_force/couple,
    gravity as density g, the muscle's active moment) of a rod scene."""
    from ..rod import DistributedLoad, EndLoad
    from ..rod.external_forces import TravellingWave
    lds, mat = scene["loads"], scene["material"]
    end_loads = []
    for end in ENDS:
        for kind in ("force", "couple"):
            spec = lds[f"{end}_{kind}"]
            for value, history in _vector_parts(spec) if spec is not None else ():
                end_loads.append(EndLoad(kind, value, history, end=end,
                                         follower=spec.follower))
    distributed = []
    for kind in ("force", "couple"):
        spec = lds[f"distributed_{kind}"]
        for value, history in _vector_parts(spec) if spec is not None else ():
            distributed.append(DistributedLoad(
                kind, _profiled(value, spec.profile or Coefficient(constant=1.0)), history,
                spec.follower))
    if lds["gravity"] is not None:
        distributed.append(DistributedLoad("force", _profiled(lds["gravity"], mat["density"])))
    if lds["muscle"] is not None:
        distributed += TravellingWave(**lds["muscle"]).loads(
            scene["geometry"]["length"])
    return end_loads, distributed


def rod_point_loads(scene: Scene) -> list:
    """PointLoads (point_force/couple) of a rod scene."""
    from ..rod import PointLoad
    return [PointLoad(kind, value, spec.s, history, spec.follower)
            for kind in ("force", "couple") if (spec := scene["loads"][f"point_{kind}"])
            for value, history in _vector_parts(spec)]


def _vector_parts(spec):
    """(value, scalar history) pairs whose sum is the vector history: value * history(t)
    for steps, ramps, ...; one pair per non-zero component for a table of 3-vectors."""
    from dataclasses import replace
    if spec.type != "table":
        return [(spec.value, replace(spec, value=1.0).build())]
    return [(tuple(np.eye(3)[i]), spec.build(i)) for i in range(3)
            if any(v[i] for v in spec.values)]


def _profiled(value, profile):
    """value * profile(s): a 3-tuple, or a callable of s (UFL and floats) if s-dependent."""
    if profile.is_constant:
        return tuple(profile.constant * np.asarray(value, float))
    return lambda s: [profile(s) * v for v in value]
