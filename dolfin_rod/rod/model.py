"""RodModel: the 3-D special Cosserat rod with evolving natural configuration (Sections
2-4) as one SemiDiscreteProblem, composed of the modules of this package:

    material.py            RodParameters and their checks
    discretisation.py      mesh, end measures, quadrature rules, spaces, unknowns
    constitutive.py        strains -> psi, m, n (eqs. mfmeq, mfneq)
    residual.py            balance, gauge, constraints, evolution, inertia
    external_forces.py     end and distributed loads, drag
    boundary_conditions.py clamped, pinned, prescribed motions, reactions
    initial_state.py       the stress-free configuration, the state at t = 0
    start.py               starting states: placement, curves, velocities
    contact.py             obstacles: barrier and Coulomb friction
    diagnostics.py         energies, powers, tip
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from ..theory import constraints
from .. import loads as load_histories
from ..theory.evolution import check_variant
from ..checks import (ENDS, MAX_CELL_TURN, N_CELLS, ROD_MODEL, ROTATION_UNKNOWNS, VARIANT,
                      check_n_cells, end_keyed, old_keywords)
from ..fem import form_cache, shared_mesh
from ..fem.fe_model import FEModel
from ..fem.gathered_form import LazyForms, data_of
from ..fem.problem import SecondOrderProblem, SemiDiscreteProblem
from ..integrators.step_control import IntegrationError
from ..mpi import largest_on_ranks
from ..theory.rotations import np_qmul, np_rotation_matrix, rotation_matrix
from .rotation_choice import choose_rotations, rotation_vector_obstacle
from . import diagnostics, external_forces, initial_state, residual, ring
from .boundary_conditions import EndSupports, linked_axes, spin_free, welded_spin_end
from .constitutive import check_model, energy_function, section_response
from .contact import (REST_PASSES, REST_TOLERANCE, ContactLaw, InitialOverlap, Obstacle,
                      ObstacleContact, Spin, check_contact)
from .discretisation import discretise, function_spaces, unknowns
from .external_forces import DistributedLoad, EndLoad, PointLoad
from .force_scale import ForceScale
from .joint_points import Joint, check_joints, check_joints_at_start
from .joints import JointReactions, joint_nodes, node_links
from .kinks import attach, piece_starts, split_at_kinks, system_starts
from .layout import RodLayout
from .linking import clamped_rod_linking
from .obstacle_segments import ObstacleSegments
from .pair_contact import SegmentContact
from .placement import placed_shape
from .material import RodParameters, coefficients, is_zero
from .rods import OLD_CONSTRAINT, OLD_ENDS, Rod, check_rods, new_keywords, positional_ends
from .segments import PassThroughCheck, exclusion_problem
from .structure import structure
from .start import RodStarts, StartingState, check_rod_starts, check_start

_CONJUGATE = np.array([1.0, -1.0, -1.0, -1.0])
# cos(MAX_CELL_TURN / 2) raised by far more than round-off (1e-9 against ~1e-16)
_COS_HALF_TURN_SAFE = math.cos(MAX_CELL_TURN / 2) * (1.0 + 1e-9)
_COS_HALF_TURN_UNIT = _COS_HALF_TURN_SAFE * (1.0 + 1e-12)   # for rows of unit size
_UNIT_GAP_SQUARED = 2.0 * (1.0 - 1e-12 - _COS_HALF_TURN_UNIT)  # of |a - b|^2 (_unit_within)
_ONES_4 = np.ones(4)


def _safely_within(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether every cell's turn, from quaternion a to quaternion b (rows), is below
    MAX_CELL_TURN by more than round-off: the turn t of conj(a) b has cos(t/2) =
    a.b / (|a| |b|), and t <= MAX_CELL_TURN iff cos(t/2) >= cos(MAX_CELL_TURN / 2)
    (t/2 in [0, pi]).  A cell closer to the limit than the margin is left to the
    exact turn (RodModel.check_cell_turns), so the bound never changes its answer."""
    # row sums as products with ones: 2x cheaper than einsum at a few cells
    dots = (a * b) @ _ONES_4
    sizes = np.sqrt(((a * a) @ _ONES_4) * ((b * b) @ _ONES_4))
    return bool((dots > _COS_HALF_TURN_SAFE * sizes).all())


def _unit_within(a: np.ndarray, b: np.ndarray) -> bool:
    """_safely_within for rows of unit size to round-off (|a|^2, |b|^2 = 1 to a few 1e-16,
    a normalised quaternion's; |a| |b| <= 1 + 1e-12): a.b > cos(MAX_CELL_TURN / 2) (1 +
    1e-9) (1 + 1e-12) >= cos(MAX_CELL_TURN / 2) (1 + 1e-9) |a| |b| for every row, and
    a.b = (|a|^2 + |b|^2 - |a - b|^2) / 2 >= 1 - 1e-12 - |a - b|^2 / 2: the sum of
    |a - b|^2 over the rows (about (total turn)^2 / cells: small on a fine mesh) bounds
    them all at once; else each row's a.b (two or four numpy calls instead of nine)."""
    d = b - a
    if np.vdot(d, d) <= _UNIT_GAP_SQUARED:
        return True
    return bool(np.einsum("ij,ij->i", a, b).min(initial=np.inf) > _COS_HALF_TURN_UNIT)


# structures as data (rod/structure.py) whose residual, made on their first model, had the
# Functions and Constants of its terms: later models make it only when it is read
_DATA_OF_TERMS: set[str] = set()
# of those whose residual had only Functions and Constants made before the terms: their
# roles (RodModel._data_roles); later models neither make the terms nor traverse them
_ROLES: dict[str, frozenset] = {}


@dataclass
class Terms:
    """A rod model's UFL (RodModel._balance): the section's response, the block terms F,
    the contact force n, the evolution's natural pairs, the (drag, friction) dissipation,
    the loads' power, each rod's springs' energy and their variations by block."""

    resp: object
    F: dict
    n: object
    natural_pairs: list
    dissipation: tuple
    power: object
    springs: list
    variations: dict


def end_frames(rod: Rod) -> dict:
    """{end: the stress-free, placed rotation (quaternion) of the rod's end}."""
    q = placed_shape(rod, np.array([0.0, float(rod.params.length)]))[1]
    return dict(zip(ENDS, q))


def oblique_supports(rod: Rod) -> list[tuple[str, str]]:
    """(end_slide or end_turn, end) of a rod's supports on a one-node link
    (boundary_conditions.linked_axes)."""
    names = {"displacement": "end_slide", "rotation_increment": "end_turn"}
    frames = end_frames(rod) if rod.end_turn else {}    # (read for end_turn only)
    return [(names[block], end) for block, end in
            linked_axes(rod.end_slide, rod.end_turn, frames)]


class RodModel(FEModel):
    """The 3-D rod as a SemiDiscreteProblem.

    model: "evolving", "kelvin_voigt" or "hyperelastic" (constitutive.py); variant:
    "local" or "uniform" (evolution.py); constraints: None, "unshearable" or
    "inextensible_unshearable" (constraints.py); start, end (the supports at s = 0 and
    s = L: "clamped", "pinned" or "free"), end_displacement, end_rotation:
    boundary_conditions.py (end_slide: {end: axis}, a clamped or pinned end sliding
    along a coordinate axis; end_turn: {end: axis}, a clamped end turning freely about
    one; end_springs: {end: EndSpring}, compliant supports); end_loads, distributed_loads,
    point_loads (at points inside the rod): external_forces.py; rotations:
    "auto", "quaternion" or "rotation_vector" (discretisation.py; "auto" takes rotation
    vectors for the local variant without a constraint, a dynamic rod with rotary
    inertia or a quasi-static one without Kelvin-Voigt viscosity and drag: 6 unknowns
    per node); obstacles with a contact law (contact.py; friction: dynamic rods).

    ``problem`` is a SemiDiscreteProblem (quaternions: any scheme of TimeStepper or
    TSIntegrator) or a SecondOrderProblem (rotation vectors: generalized-alpha on the
    rotation group, integrators/lie_alpha.py, which TimeStepper uses for it).
    Several rods in one model: system.RodSystem.  The keywords are the scene's keys
    (docs/rod.md, "One vocabulary"); ``ends=(start, end)`` and ``constraint`` are
    deprecated names of ``start``, ``end`` and ``constraints``.
    """

    @old_keywords("RodModel", OLD_ENDS | OLD_CONSTRAINT, new_keywords)
    def __init__(self, params: RodParameters, n_cells: int = N_CELLS, model: str = ROD_MODEL,
                 variant: str = VARIANT, constraints: str | None = None,
                 start: str = "clamped",
                 end_loads: Sequence[EndLoad] = (),
                 distributed_loads: Sequence[DistributedLoad] = (),
                 end_displacement: dict | None = None, end_rotation: dict | None = None,
                 rotations: str = ROTATION_UNKNOWNS, comm: MPI.Comm = MPI.COMM_WORLD,
                 end_slide: dict | None = None, obstacles: Sequence[Obstacle] = (),
                 contact: ContactLaw | None = None, end_springs: dict | None = None,
                 end_turn: dict | None = None, end: str = "free",
                 point_loads: Sequence[PointLoad] = (), closed: bool = False,
                 excess_link: float = 0.0):
        start, end = positional_ends("RodModel", start, end, stacklevel=5)
        keyed = end_keyed("RodModel", dict(    # "left", "right": deprecated (the caller's line)
            end_displacement=end_displacement, end_rotation=end_rotation, end_slide=end_slide,
            end_springs=end_springs, end_turn=end_turn), stacklevel=3)
        rod = Rod(params, n_cells, start, end_loads, distributed_loads, point_loads=point_loads,
                  end=end, closed=closed, excess_link=excess_link, **keyed)
        self._build([rod], model, variant, constraints, rotations, comm, obstacles=obstacles,
                    contact=contact)

    def _build(self, rods: list[Rod], model: str, variant: str, constraint: str | None,
               rotations: str, comm, joints: Sequence[Joint] = (),
               obstacles: Sequence[Obstacle] = (), contact: ContactLaw | None = None) -> None:
        """The model of one or several rods and their joints (see system.RodSystem); a
        rod with corners in its stress-free polyline as the pieces between them, joined
        rigidly (kinks.py)."""
        joints = self._check_and_lay_out(rods, model, variant, constraint, joints, comm)
        if not obstacles:       # (an obstacle or a joint may hold a ring's mechanism)
            joined = {name for joint in joints for name in joint.rods}
            ring.check_mechanism([rod for rod in self.user_rods if rod.name not in joined],
                                 self.dynamic)
        # rods welded into one body, pinned at two ends: its spin held (welded_spin_end)
        self.welded_spin = None if self.dynamic else welded_spin_end(
            self.rods, [joint.kind for joint in joints])
        self.rotations = self._rotation_unknowns(rotations, joints)
        disc = discretise(comm, self.layout, self.rotations)
        super().__init__(disc.mesh)
        self.dx, self.dx_r = disc.dx, disc.dx_r
        self.pieces = disc.pieces
        # every Function and Constant of the terms first, in the order in which the terms
        # made them before (their order is the kernels' and the registry's: form_cache),
        # then the terms (UFL): made at their first read (_terms)
        self._section_data(disc)
        # several rods and obstacles: the response's Functions before the obstacles'
        response = self._response_terms(disc) if obstacles and not self.layout.single else None
        self.contact = self._obstacle_contact(obstacles, contact, disc)
        zero = residual.diagonal_zero(self.unknowns, disc)
        self.loads, loads = external_forces.load_data(
            disc, [(k, load) for k, rod in enumerate(self.rods) for load in rod.end_loads],
            [(k, load) for k, rod in enumerate(self.rods) for load in rod.distributed_loads],
            [(k, load) for k, rod in enumerate(self.rods) for load in rod.point_loads])
        self._end_supports()
        self.force_scale = ForceScale(self.rods, loads, self.end_supports)
        self._made_terms, self._xi = None, None
        self._cell_nodes = None     # each cell's two nodes (check_cell_turns)
        self._make_terms = lambda: self._balance(disc, zero, loads, response)
        text = structure(rods, model, variant, constraint, self.rotations, comm.size, joints,
                         obstacles, contact)
        forms = self._residual_forms(disc, text, self._data_roles(zero, loads))
        self.joints = list(joints)
        nodes = joint_nodes(self, self.joints)
        # segments joined at a joint or a ring's weld are neighbours
        neighbours = nodes + ring.weld_nodes(self)
        self.segment_contact = self._segment_contact(contact, self.layout, neighbours)
        self.obstacle_segments = self._obstacle_segments(obstacles, contact, self.layout)
        # the terms of segment contact that fem/assembly adds (pair_contact.BoundTerm)
        self.segment_terms = [t for t in (self.segment_contact, self.obstacle_segments) if t]
        self.problem = self._problem(forms, node_links(self, self.joints, nodes)
                                     + ring.weld_links(self) + [
            line for supports in self.end_supports for line in supports.links(self.names)])
        self.problem.unset_state = "model.set_initial_state()"     # zero quaternions
        if self.dynamic:       # the steps must resolve them (integrators' check_run)
            self.problem.prescribed_motions = {
                (f"rods {self.rod_names[k]!r}: " if len(self.splits) > 1 else "")
                + f"{name}[{end!r}]": motion for k, rod in enumerate(self.rods)
                for name in ("end_displacement", "end_rotation")
                for end, motion in (getattr(rod, name) or {}).items()}
        self.problem.structure = text
        self.joint_reactions = JointReactions(self, self.joints, nodes) if joints else None
        self._diagnostics(disc, neighbours, contact)

    def _check_and_lay_out(self, rods: list[Rod], model: str, variant: str,
                           constraint: str | None, joints: Sequence[Joint], comm) -> list[Joint]:
        """Refuse bad input before any mesh; the rods' data (a rod split at its kinks:
        its pieces, ``splits``: kinks.Split of each rod) and their layout on one mesh; the
        joints (on the pieces, with the corners')."""
        check_model(model, rods[0].params)
        check_variant(variant)
        constraints.check_constraint(constraint, dynamic=not is_zero(rods[0].params.density))
        check_rods(rods, model, variant)
        check_joints(list(joints), rods)
        ring.check_closed(rods, dynamic=not is_zero(rods[0].params.density))
        self.splits = splits = [split_at_kinks(ring.welded_ends(rod)) for rod in rods]
        self.kinked = any(len(split.rods) > 1 for split in splits)
        self.user_rods = rods
        length = max(float(rod.params.length) for rod in rods)
        joints = attach(list(joints), splits)
        rods = [piece for split in splits for piece in split.rods]
        # each piece's rod (its name: the first piece's)
        self.rod_names = [split.rods[0].name for split in splits for _ in split.rods]
        check_n_cells(sum(rod.n_cells for rod in rods), comm.size)   # cells per rank
        self.rods = rods
        self.params, self.model, self.variant, self.constraint = (rods[0].params, model,
                                                                  variant, constraint)
        self.end_loads = [load for rod in rods for load in rod.end_loads]
        self.distributed_loads = [load for rod in rods for load in rod.distributed_loads]
        self.point_loads = [load for rod in rods for load in rod.point_loads]
        self.layout = layout = RodLayout(tuple(rod.name for rod in rods),
                                         tuple(float(rod.params.length) for rod in rods),
                                         tuple(rod.n_cells for rod in rods),
                                         tuple(offset for split in splits
                                               for offset in split.offsets)
                                         if self.kinked else ())
        self.length = length
        self.evolving = model == "evolving"
        self.dynamic = not is_zero(rods[0].params.density)
        # forces of the rates of positions and rotations (Kelvin-Voigt viscosity, drag):
        # a quasi-static rod's positions then move at a viscous rate, they cannot jump
        self.rate_dependent = not all(is_zero(v) for rod in rods for v in (
            rod.params.M, rod.params.N, rod.params.drag, rod.params.rotational_drag,
            rod.params.spatial_rotational_drag))
        return joints

    def _rotation_unknowns(self, rotations: str, joints: Sequence[Joint]) -> str:
        """The rotation unknowns ("quaternion" or "rotation_vector") the rods can have
        (rotation_choice.py), refused where joints or a jumping end motion need others."""
        rods, all_params = self.rods, [rod.params for rod in self.rods]
        obstacle = rotation_vector_obstacle(
            self.dynamic, self.variant, self.constraint,
            rotary_inertia=not any(any(map(is_zero, p.section_inertia)) for p in all_params),
            rate_dependent=self.rate_dependent,
            rotation_held=self.welded_spin is not None or any(
                "clamped" in rod.ends or bool(rod.end_rotation)
                or spin_free(rod.ends, rod.end_rotation, rod.end_turn, rod.end_springs)
                or any(np.all(spring.stiffness("rotational"))
                       for spring in (rod.end_springs or {}).values())
                for rod in rods))
        # an oblique slide is a line of the position (and velocity) with any unknowns; an
        # oblique turn a line of the rotation increment: rotation vectors only (with
        # quaternions it holds q in a plane, span(q_0, q_0 (0, a)), not a line)
        linked = [f"{name}[{end!r}]" for rod in rods for name, end in oblique_supports(rod)
                  if name == "end_turn"]
        # joints: the system's, or only the rigid corners of a kinked rod (kinks.py)
        what = ("joints need" if len(joints) > sum(len(split.joints) for split in self.splits)
                else "a stress-free polyline with corners (split there into pieces joined "
                     "rigidly, rod/kinks.py) needs")
        if any(rod.closed and rod.start == "free" for rod in rods):   # ring.weld_links
            joints, what = [*joints, "weld"], "a free ring's weld (closed, start 'free') needs"
        if joints and obstacle:
            raise ValueError(f"{what} rotation-vector unknowns, which this "
                             f"{'system' if len(self.splits) > 1 else 'rod'} cannot have: "
                             f"{obstacle}")
        if linked and obstacle:
            raise ValueError(f"{linked[0]}: a turn about an axis off the coordinate axes "
                             f"needs rotation-vector unknowns, which this rod cannot have: "
                             f"{obstacle}")
        # a dynamic rod's end rotation jumps at most at t = 0 (later: refused): the
        # consistent start turns it there (integrators/lie_alpha.py)
        chosen = choose_rotations(rotations, obstacle, rotation_jumps=not self.dynamic and any(
            load_histories.jumps(motion) for rod in rods
            for motion in (rod.end_rotation or {}).values()))
        if joints and chosen != "rotation_vector":
            raise ValueError(f"{what} rotation-vector unknowns (rotations 'auto' or "
                             f"'rotation_vector'), got {rotations!r}")
        if linked and chosen != "rotation_vector":
            raise ValueError(f"{linked[0]}: a turn about an axis off the coordinate axes "
                             "needs rotation-vector unknowns (rotations 'auto' or "
                             f"'rotation_vector'), got {rotations!r}")
        for name in ("end_displacement", "end_rotation"):
            if self.dynamic and chosen == "quaternion" and any(
                    load_histories.jumps(motion) for rod in rods
                    for motion in (getattr(rod, name) or {}).values()):
                raise ValueError(f"{name} starts away from 0 on a dynamic rod: its "
                                 "consistent start (at rest in equilibrium with the moved "
                                 "end) is that of rotation-vector unknowns (rotations = "
                                 f"'rotation_vector'), not of {chosen!r}")
        return chosen

    def _section_data(self, disc) -> None:
        """The unknowns, the material coefficients and the reference strains on the
        discretisation."""
        per_rod = self.variant == "uniform" and not self.layout.single   # each rod's strains
        self.unknowns = unk = unknowns(function_spaces(
            disc.mesh, self.evolving, self.variant, self.constraint, self.dynamic,
            self.rotations, len(self.rods)), self.dynamic,
            disc.pieces.of_rods if per_rod else None)
        self.names, self.f, self.r, self.t = unk.names, unk.f, unk.r, unk.t
        self.V, self.W = unk.V, unk.W
        self.coefficients = c = coefficients([rod.params for rod in self.rods], disc.pieces)
        self.J = c["J"]
        S_ref = shared_mesh.space(disc.mesh, "reference strains", lambda: fem.functionspace(
            disc.mesh, ("DG", 0, (3,))))                      # set by the initial state
        self.reference = (fem.Function(S_ref, name="u_ref"), fem.Function(S_ref, name="v_ref"))

    def _response_terms(self, disc) -> tuple:
        """The section's response (strains, psi, m, n: constitutive.py) and the block
        residuals of the balance laws, evolution, inertia and drag: (response, F, n, the
        evolution's natural pairs, the drag's dissipation).  Several rods make Functions
        here (layout.Pieces: indicators, lengths)."""
        unk, c, rods = self.unknowns, self.coefficients, self.rods
        psi_fn = energy_function(rods[0].params, c, self.evolving, *self.reference)
        # an active moment's power M . u_t (external_forces.apply_loads) reads u_t
        moments = any(load.kind == "moment" for load in self.distributed_loads)
        resp = section_response(unk, c, psi_fn, self.evolving, self.constraint, self.reference,
                                rates=moments)
        F, n = residual.internal_forces(unk, resp, self.constraint, disc)
        residual.gauge(F, unk, disc)
        natural_pairs = (residual.evolution(F, unk, resp, c, self.variant, self.constraint,
                                            disc) if self.evolving else [])
        if self.dynamic:
            residual.inertia(F, unk, c, disc)
        drag_dissipation = external_forces.drag(F, unk, c, [rod.params for rod in rods], disc,
                                                 resp.v)
        return resp, F, n, natural_pairs, drag_dissipation

    def _balance(self, disc, zero, loads, response: tuple | None = None) -> Terms:
        """The model's terms: the response's (``response``, made before, or now:
        _response_terms), the obstacles' contact and the loads (their Functions and
        Constants made before: ``zero``, ``loads``), the supports' springs
        (_spring_terms); the friction's dissipation and the loads' power."""
        unk = self.unknowns
        resp, F, n, natural_pairs, drag_dissipation = response or self._response_terms(disc)
        friction_dissipation = (self.contact.add_to(F, unk.t["displacement"])
                                if self.contact else 0)
        residual.zero_diagonals(F, unk, disc, zero)
        power = external_forces.apply_loads(F, unk, disc, loads, (resp.u, resp.u_t))
        springs, variations = self._spring_terms(disc)
        return Terms(resp, F, n, natural_pairs, (drag_dissipation, friction_dissipation),
                     power, springs, variations)

    def _terms(self) -> Terms:
        """The model's UFL terms (_balance), made at the first call."""
        if self._made_terms is None:
            self._made_terms, self._make_terms = self._make_terms(), None
        return self._made_terms

    def _data_roles(self, zero, loads) -> dict:
        """The Functions and Constants made before the terms, by role (the same roles in
        every model of a structure): the unknowns' fields, rates, accelerations, the
        stored rotations, the material coefficients, the reference strains, the zero of
        the diagonals, the loads' and the springs' Constants."""
        unk = self.unknowns
        roles: dict = {}
        for kind, fields in (("field", unk.f), ("rate", unk.r), ("acceleration", unk.acc)):
            roles.update({(kind, name): g for name, g in fields.items()})
        if unk.chart is not None:
            roles.update({("chart", name): getattr(unk.chart, name)
                          for name in ("s_mid", "q_n", "eta")})
        roles.update({("coefficient", name): value for name, value in self.coefficients.items()
                      if isinstance(value, (ufl.Coefficient, ufl.Constant))})
        roles.update({("reference", k): g for k, g in enumerate(self.reference)})
        if zero is not None:
            roles[("zero",)] = zero
        for j, load in enumerate(loads):
            roles.update({("load", j, name): const for name, const in load.constants().items()})
        for k, supports in enumerate(self.end_supports):
            roles.update({("spring", k, end, i): const for end, pair in supports.rest.items()
                          for i, const in enumerate(pair)})
        return roles

    def _residual_forms(self, disc, text: str | None, roles: dict):
        """The block residuals: the terms F made into one Form per block
        (residual.one_quadrature_rule) plus the compliant supports' variations, made when
        first read (gathered_form.LazyForms) for a model whose structure ``text`` had a
        model before: their data are the Functions and Constants of the roles its forms
        had (``roles``: _data_roles; the terms are not made), else those of the terms
        (data_of).  The first model of a structure makes them now, checks that they have
        the data of their terms and records their roles."""
        unk, names = self.unknowns, list(self.names)

        def make() -> list:
            terms = self._terms()
            residual.one_quadrature_rule(terms.F, unk, disc)
            for block, variation in terms.variations.items():
                terms.F[block] += variation
            return [terms.F[name] for name in names]

        known = _ROLES.get(text)
        if known is not None and known <= roles.keys():
            return LazyForms(make, len(names), {roles[role] for role in known})
        terms = self._terms()
        data = data_of([itg for form in [*(terms.F[name] for name in names),
                                         *terms.variations.values()]
                        for itg in form.integrals()])
        forms = LazyForms(make, len(names), data)
        if text is not None and text in _DATA_OF_TERMS:
            return forms
        made = list(forms)
        if text is not None and form_cache.registry(made) == form_cache.registry(forms):
            _DATA_OF_TERMS.add(text)
            role_of = {id(obj): role for role, obj in roles.items()}
            if all(id(obj) in role_of for obj in data):
                _ROLES[text] = frozenset(role_of[id(obj)] for obj in data)
        return made

    psi = property(lambda self: self._terms().resp.psi, doc="free energy per length psi")
    m = property(lambda self: self._terms().resp.m, doc="contact couple m (material)")
    u = property(lambda self: self._terms().resp.u, doc="curvature strain u")
    v = property(lambda self: self._terms().resp.v, doc="stretch strain v")
    u_d = property(lambda self: self._terms().resp.u_d, doc="natural curvature u_d")
    v_d = property(lambda self: self._terms().resp.v_d, doc="natural stretch v_d")
    n = property(lambda self: self._terms().n, doc="contact force n (material: "
                 "constitutive + the constraint's multiplier; None if inextensible)")

    @property
    def xi(self):
        """The dissipation rate density xi (eq. disspw)."""
        if self._xi is None:
            terms = self._terms()
            self._xi = diagnostics.dissipation_density(terms.resp, self.coefficients,
                                                       terms.natural_pairs)
        return self._xi

    @property
    def residual(self) -> dict:
        """The block residuals (ufl.Form) by block name."""
        return dict(zip(self.names, self.problem.residual))

    def _end_supports(self) -> None:
        """Every rod's end supports (their Dirichlet conditions and Constants)."""
        held = self.welded_spin
        # the stress-free end frames (~40 us a rod): read for an end_turn's axis, and with
        # quaternions for a free spin's plane (EndSupports)
        quaternions = "rotation_increment" not in self.unknowns.spaces
        self.end_supports = [EndSupports(self, rod.ends, rod.end_displacement,
                                         rod.end_rotation, rod.end_slide, self.layout.span(k),
                                         rod.end_springs, rod.end_turn,
                                         end_frames(rod) if rod.end_turn or quaternions
                                         else None,
                                         spin_at=held[1] if held and held[0] == k else None)
                             for k, rod in enumerate(self.rods)]

    def _spring_terms(self, disc):
        """Each rod's springs' energy (0 without springs) and the variations of the
        compliant supports' energy that the balance adds, {block: ufl.Form}."""
        unk = self.unknowns
        per_rod = [supports.spring_energy(unk, disc.ds, disc.end_weight,
                                          disc.pieces.indicator(k))
                   for k, supports in enumerate(self.end_supports)]
        springs = sum(per_rod, 0)
        if not any(supports.springs for supports in self.end_supports):
            return per_rod, {}
        return per_rod, {block: ufl.derivative(springs, unk.f[block], unk.t[block])
                         for block in ("displacement", unk.rotation)}

    def _diagnostics(self, disc, joint_nodes, law) -> None:
        """Tips, the energy forms (diagnostics.py) and the check that the rod does not
        pass through itself (segments joined at ``joint_nodes`` are neighbours; pairs
        that the contact ``law`` keeps apart are left to it)."""
        unk, c, layout = self.unknowns, self.coefficients, self.layout
        self.tips = [diagnostics.Tip(unk, layout.span(k)[1]) for k in range(len(self.rods))]
        points = [dict.fromkeys((layout.starts[k], layout.lengths[k] / layout.n_cells[k],
                                 load.s) for load in rod.point_loads)
                  for k, rod in enumerate(self.rods)]
        self.point_positions = diagnostics.PointPositions(
            unk, dict.fromkeys(p for own in points for p in own))
        # a system's rods: each its own points ("<name>.point{j}_position_{xyz}"; a rod
        # split at its corners: its pieces' in turn)
        self.rod_point_positions = [diagnostics.PointPositions(unk, dict.fromkeys(
            p for own, rod in zip(points, self.rod_names) if rod == name for p in own))
            for name in dict.fromkeys(self.rod_names)]

        def energy_forms() -> dict:
            terms = self._terms()
            resp, springs = terms.resp, terms.springs
            drag_dissipation, friction_dissipation = terms.dissipation
            forms = diagnostics.energy_forms(resp, self.xi, c, unk, disc, terms.power,
                                             drag_dissipation + friction_dissipation,
                                             sum(springs, 0))
            if len(self.splits) > 1:    # each rod's own energies, "<name>.free_energy", ...
                for name in dict.fromkeys(self.rod_names):
                    own = [k for k, rod in enumerate(self.rod_names) if rod == name]
                    forms.update(diagnostics.rod_energy_forms(
                        name, resp, c, unk, disc, sum(disc.pieces.indicator(k) for k in own),
                        sum((springs[k] for k in own), 0)))
            if self.contact:
                forms.update(self.contact.diagnostic_forms())
                forms["friction_dissipation"] = (friction_dissipation
                                                 or 0 * resp.psi * disc.dx_r)
            return forms

        self.set_diagnostic_forms(energy_forms)      # made at the first diagnostics
        h = min(length / n for length, n in zip(layout.lengths, layout.n_cells))
        self.pass_through = PassThroughCheck(
            unk.f["displacement"], distance=h, exclusion=3 * h,
            hint="self-contact is off: set contact.self = true (contact.between_rods for "
                 "rods of a system; docs/contact.md)" if len(layout.rods) == 1 else
                 "contact between rods is off: set contact.between_rods = true "
                 "(contact.self for a rod through itself; docs/contact.md)", layout=layout,
            names=self.rod_names, joints=joint_nodes,
            covered=(bool(law and law.self), bool(law and law.between_rods)))

    def _segment_contact(self, law, layout, joint_nodes) -> SegmentContact | None:
        """The segment pairs' contact (pair_contact.py) if the law asks for it; the
        joints' nodes (s of both rods) join their segments as neighbours."""
        if law is None or not (law.self or law.between_rods):
            return None
        h = max(length / n for length, n in zip(layout.lengths, layout.n_cells))
        problem = exclusion_problem(law.radius, law.gap, h, min(
            float(rod.params.length) for rod in self.user_rods))   # a kinked rod: all of it
        if law.self and problem:
            raise ValueError(problem)
        check_contact([], law)
        self._check_pair_friction(law)
        contact = SegmentContact(self.unknowns.f["displacement"], law, layout.rod_of,
                                 law.self, law.between_rods, joint_nodes,
                                 velocity=self.unknowns.V if self.dynamic else None,
                                 along=layout.along)
        contact.block = list(self.names).index("displacement")
        contact.rod_names = layout.rods
        P1 = fem.functionspace(self.mesh, ("Lagrange", 1, (3,)))
        self.pair_force = fem.Function(P1, name="pair_contact_force")
        return contact

    def _obstacle_segments(self, obstacles, law, layout) -> ObstacleSegments | None:
        """The segment contact of the obstacles that act on the segments
        (obstacle_segments.py; ObstacleContact.segment_obstacles), None if none does."""
        if not self.contact or not self.contact.segment_obstacles:
            return None
        on = [(k, obstacles[k]) for k in self.contact.segment_obstacles]
        rubbing = [k for k, ob in on if ob.friction > 0]
        if rubbing and self.unknowns.chart is None:
            raise ValueError(f"obstacles[{rubbing[0]}].friction on the segments needs "
                             "rotation-vector unknowns (advanced by generalized-alpha, whose "
                             f"velocities the friction follows), got {self.rotations!r}")
        contact = ObstacleSegments(self.unknowns.f["displacement"], law, on, layout.rod_of,
                                   self.contact.h, self.unknowns.V if rubbing else None)
        if not len(contact.index):      # meshes without sharp edges
            return None
        contact.block = list(self.names).index("displacement")
        P1 = fem.functionspace(self.mesh, ("Lagrange", 1, (3,)))
        self.segment_force = fem.Function(P1, name="obstacle_segment_force")
        return contact

    def _check_pair_friction(self, law) -> None:
        """Friction between segments (pair_friction.py) follows the velocities of
        generalized-alpha's steps: a dynamic rod with rotation-vector unknowns."""
        if not (law.self_friction or law.between_rods_friction):
            return
        key = "self_friction" if law.self_friction else "between_rods_friction"
        if not self.dynamic:
            raise ValueError(f"contact.{key} needs a dynamic rod (rho_A > 0): the "
                             "friction force depends on the velocity")
        if self.unknowns.chart is None:
            raise ValueError(f"contact.{key} needs rotation-vector unknowns (advanced by "
                             "generalized-alpha, whose velocities the friction follows), got "
                             f"{self.rotations!r}")

    def _obstacle_contact(self, obstacles, law, disc) -> ObstacleContact | None:
        if not obstacles:
            return None
        if law is None:
            raise ValueError("obstacles need a contact law (contact = ContactLaw(...))")
        if any(ob.friction > 0 for ob in obstacles) and not self.dynamic:
            raise ValueError("obstacles[k].friction needs a dynamic rod (density > 0): "
                             "the friction force depends on the velocity")
        unk = self.unknowns
        return ObstacleContact(obstacles, law, disc, unk.f["displacement"],
                               unk.V if self.dynamic else None,
                               Spin(unk.q, unk.W, unk.dTheta, unk.rotation)
                               if self.dynamic else None,
                               (unk.acc["displacement"], unk.acc[unk.rotation])
                               if unk.acc else None)

    @property
    def supports(self) -> EndSupports:
        """The supports of the rod's ends (of the first rod of a system)."""
        return self.end_supports[0]

    def set_supports(self, t: float) -> None:
        """The prescribed end values of every rod at time t."""
        for supports in self.end_supports:
            supports.set(t)

    def _problem(self, forms, links: list) -> SemiDiscreteProblem:
        unk = self.unknowns
        blocks = ([unk.f[n] for n in self.names], [unk.r[n] for n in self.names],
                  forms, self.loads, self.bcs, self.set_supports)
        terms = list(self.segment_terms)
        if self.contact and self.contact.term:     # a mesh obstacle's features
            terms.append(self.contact.term)
        where, scale = self.where_failed, self.force_scale_now
        if unk.chart is None:           # links: oblique slides (no joints: refused)
            return SemiDiscreteProblem(*blocks, after_step=self.commit_rotations,
                                       check_step=self.check_step, terms=terms,
                                       where_failed=where, links=links, force_scale=scale,
                                       inertia=self.dynamic)
        rates_used = set(form_cache.registry(forms))
        return SecondOrderProblem(
            *blocks, accelerations=[unk.acc.get(n) for n in self.names],
            after_step=self.commit_rotations, check_step=self.check_step,
            time_orders=[2 if n in unk.acc else 1 if unk.r[n] in rates_used else 0
                         for n in self.names], lie_group=True,
            error_scales=[1.0 if n == unk.rotation else self.length for n in self.names],
            links=links, terms=terms, scale_motions=self.scale_motions,
            motion_turn=self.motion_turn, where_failed=where, force_scale=scale,
            inertia=self.dynamic,
            friction_lookahead=self.contact.lookahead if self.contact else None,
            rest_in_contact=self._rest_on_obstacles if self.contact and self.dynamic
            else None)

    def force_scale_now(self) -> float:
        """The size of the forces (force_scale.py) at the time of the supports' values."""
        return self.force_scale(self.end_supports[0].time_set)

    def _rest_on_obstacles(self, solve) -> None:
        """The start's rest of nodes laid within an obstacle's barrier
        (SecondOrderProblem.rest_in_contact): passes of ObstacleContact.rest_on_barriers
        (rho_A at the owned nodes), the starting accelerations solved again by ``solve``
        after each, until no node moves by REST_TOLERANCE delta.  Where the passes do not
        settle it (the imbalance grows: a node held near a support, whose bending answers
        a move more stiffly than the barrier; or REST_PASSES run out) the rod starts where
        it was given.  The friction's lagged normal forces and the path check's points
        follow the state."""
        x = self.unknowns.f["displacement"]
        owned = x.function_space.dofmap.index_map.size_local
        s = x.function_space.tabulate_dof_coordinates()[:owned, 0]
        rod_of, mass = self.layout.rod_of(s), np.zeros(len(s))
        for k, rod in enumerate(self.rods):
            on = rod_of == k
            rho = rod.params.density
            mass[on] = rho(s[on] - self.layout.starts[k]) if callable(rho) else rho
        given, before = x.x.array.copy(), math.inf
        for _ in range(REST_PASSES):
            move, imbalance = self.contact.rest_on_barriers(mass)
            if move <= REST_TOLERANCE or not imbalance <= before:
                break
            before = imbalance
            self._contact_state_moved()
            solve()
        else:
            move = math.inf
        if move > REST_TOLERANCE:       # not settled: the start as given
            x.x.array[:] = given
            self._contact_state_moved()
            solve()

    def _contact_state_moved(self) -> None:
        self.contact.update_normal_forces()
        self.contact.commit()

    def where_failed(self) -> str | None:
        """Where a step that finally failed went wrong (step_control.step_failure): the
        segment pair nearest to touching, the obstacle nearest the centre line."""
        said = [where() for where in (
            self.segment_contact and self.segment_contact.nearest_pair,
            self.contact and self.contact.nearest_obstacle) if where]
        return "; ".join(w for w in said if w) or None

    def scale_motions(self, fraction: float) -> None:
        """Every rod's prescribed end motions scaled by ``fraction`` (EndSupports.scale)."""
        for supports in self.end_supports:
            supports.scale(fraction)

    def motion_turn(self, t: float) -> float:
        """The largest angle by which a prescribed end rotation of any rod turns its end
        at time t (EndSupports.largest_turn)."""
        return max(supports.largest_turn(t) for supports in self.end_supports)

    def commit_rotations(self) -> None:
        """After an accepted step: rotation vectors q_n <- q_n c(theta), theta <- 0; the
        friction's lagged normal forces."""
        if self.unknowns.chart is not None:
            self.unknowns.chart.commit()
            for supports in self.end_supports:
                supports.commit()
        if self.contact:
            self.contact.update_normal_forces()
            self.contact.commit()
        for contact in self.segment_terms:
            contact.commit()
        self.check_cell_turns(unit=self.unknowns.chart is not None)

    def check_cell_turns(self, unit: bool = False) -> None:
        """IntegrationError when a cell's end node turned by more than checks.MAX_CELL_TURN
        against its start node (issue 28 item 4): beyond it the rotation interpolation
        between two nodes misrepresents the turn (a strain that blows up, or a wrap to a
        wrong, smaller twist), whatever turns the rod (end couples, prescribed rotations,
        whirling).  The turn is that of the nodes' own quaternions (continuous in time:
        no sign flips), in [0, 2 pi]; the same answer on every rank.  Called after every
        step, where the turns are far below the limit: a rank whose cells all pass the
        bound _safely_within (a dot product per cell) computes no turn.  ``unit``: the
        quaternions are of unit size to round-off (a chart's, normalised by its commit),
        and the bound needs no sizes (_unit_within)."""
        if self._cell_nodes is None:
            self._cell_nodes = self._cell_node_rows()
        nodes, first, second = self._cell_nodes
        a, b = nodes[first], nodes[second]
        local = 0.0
        if not (_unit_within(a, b) if unit else _safely_within(a, b)):
            p = np_qmul(a * _CONJUGATE, b)
            turns = 2.0 * np.arctan2(np.linalg.norm(p[:, 1:], axis=1), p[:, 0])
            local = float(turns.max(initial=0.0))
        largest = largest_on_ranks(self.mesh.comm, local)
        if largest <= MAX_CELL_TURN:
            return
        cells_now = sum(rod.n_cells for rod in self.rods)
        t = self.end_supports[0].time_set
        raise IntegrationError(
            f"at t = {t:.6g} a cell's end node turned by {largest:.4g} rad against its "
            f"start node, more than the {MAX_CELL_TURN:g} rad the rotation interpolation "
            "between two nodes represents (beyond, the turn is misrepresented or wraps): "
            f"take n_cells >= {math.floor(cells_now * largest / MAX_CELL_TURN) + 1} for the "
            f"turn so far ([geometry.n_cells]; now {cells_now}; more for a larger turn), "
            "or turn it less (loads.end_couple, boundary.end_rotation)", t)

    def _cell_node_rows(self) -> tuple:
        """(the nodal quaternions' rows, a view of the array the steps update in place;
        each cell's first nodes' rows, its second nodes'): slices where cell k joins
        nodes k and k + 1 (one rod's dofs in order: no copy, no index conversion), else
        indices in numpy's own type (int32 costs a conversion at each use)."""
        chart = self.unknowns.chart
        q = chart.q_n if chart is not None else self.unknowns.f["quaternion"]
        cells = q.function_space.dofmap.list
        first, second = cells[:, 0].astype(np.intp), cells[:, 1].astype(np.intp)
        n = len(first)
        if np.array_equal(first, np.arange(n)) and np.array_equal(second, first + 1):
            first, second = slice(0, n), slice(1, n + 1)
        return q.x.array.reshape(-1, 4), first, second

    def check_step(self) -> str | None:
        """A reason to redo a converged step (rotation vectors: a rotation by more than
        pi/2; contact: a node inside an obstacle), else None."""
        chart = self.unknowns.chart
        reason = chart.check_increment() if chart is not None else None
        if reason is None and self.contact:
            named = len(self.end_supports) > 1
            reason = self.contact.check_state({
                supports.s_ends[end]: f"boundary.{end}_displacement"
                + (f" (rod {self.rod_names[i]})" if named else "")
                for i, supports in enumerate(self.end_supports) for end in supports.displacement})
        for contact in self.segment_terms:
            if reason is None:
                reason = contact.check_state()
        return reason

    def checkpoint_state(self) -> dict:
        """Rotation vectors: the stored rotations and the time they belong to."""
        if self.unknowns.chart is None:
            return {}
        return {"functions": {"stored_rotation": self.unknowns.chart.q_n},
                "rotations_committed_at": self.supports.committed_time}

    def restore_state(self, state: dict) -> None:
        """After the checkpoint's functions were read (checkpoint_state); the contacts'
        path checks start from the restored state."""
        if self.unknowns.chart is not None:
            committed = state["rotations_committed_at"]
            for supports in self.end_supports:
                supports.committed_time = None if committed is None else float(committed)
        for contact in (self.contact, *self.segment_terms):
            if contact:
                contact.commit()

    def hold_ends(self) -> None:
        """After the state was replaced by a saved one (a run starting from another's,
        output/from_run.py): the ends' supports, prescribed motions and springs start
        where the state has its ends; the contacts' path checks start from it."""
        initial_state.hold_ends(self)
        self.restore_state({"rotations_committed_at": None})

    def stress_free(self, s):
        """(r, q) of the initial stress-free configuration at parameter values s."""
        return initial_state.stress_free(self, s)

    def set_initial_state(self, natural_curvature=None, natural_stretch=None,
                          start: StartingState | dict | None = None) -> None:
        """Natural strains equal to the discrete reference strains of the stress-free
        configuration (a straight rod along e_3, or the helix/circle of constant
        reference_curvature; uniform variant: their mean) unless given (3-vectors; a
        system: one for every rod, or {rod name: 3-vector} for some rods).
        ``start`` None: the rod rests in that configuration, no stress at t = 0;
        a StartingState (rod/start.py; a system: {rod name: StartingState}, each in its
        rod's placed frame, rod/start.RodStarts, consistent at the joints): placed at its position
        and orientation, on its starting curve (e.g. Arc, Helix, Polyline, a Straight one
        stretched), with its velocities (dynamic rods), or settled in static equilibrium
        with the loads at t = 0 (``equilibrium``); the stress-free shape is unchanged."""
        for name, given in (("natural_curvature", natural_curvature),
                            ("natural_stretch", natural_stretch)):
            initial_state.check_natural(name, given, [rod.name for rod in self.user_rods])
        natural_curvature, natural_stretch = (
            {piece.name: given[rod] for piece, rod in zip(self.rods, self.rod_names)
             if rod in given} if isinstance(given, dict) else given     # a rod's: its pieces'
            for given in (natural_curvature, natural_stretch))
        held = initial_state.supported(self)
        if len(self.splits) == 1:
            check_start(start, self.length, self.dynamic, supported=held)
            if self.rods[0].closed:
                start = ring.closed_start(self.rods[0], start)
        if len(self.splits) == 1 and self.kinked and start is not None:
            start = RodStarts(piece_starts(start, self.splits[0]), self.rods, self.layout)
        elif len(self.splits) > 1 and (start is not None or any(
                rod.closed for rod in self.user_rods)):     # pieces: each its share
            if start is not None:
                check_rod_starts(start, self.user_rods, self.dynamic, supported=held)
            start = system_starts(ring.closed_starts(self.user_rods, start), self.splits)
            check_joints_at_start(self.rods, self.joints, start)
            start = RodStarts(start, self.rods, self.layout)
        self._starting_accelerations("balance" if start is None else start.acceleration)
        initial_state.set_initial_state(self, natural_curvature, natural_stretch, start)
        self.problem.unset_state = ""
        self.check_overlaps()
        if self.contact:
            self.contact.update_normal_forces()
            self.contact.commit()
        if self.obstacle_segments:
            self.obstacle_segments.commit()
        if self.segment_contact:
            self.segment_contact.commit()

    def check_overlaps(self) -> None:
        """Collective: InitialOverlap if the state has a node within r of an obstacle
        (or a segment within R + r of a thin one), PairOverlap (segments.py) if two
        segments' capsules overlap: the start's check, also of a state read from a run
        (output/from_run.py)."""
        if self.contact:
            self.contact.check_initial()
        if self.obstacle_segments:
            g, s, k = self.obstacle_segments.closest()
            if g <= 0:
                raise InitialOverlap.at("segment", s, g, k, self.obstacle_segments.law.gap,
                                        self.contact.obstacles[k].shape)
        if self.segment_contact:
            overlap = self.segment_contact.initial_overlap()
            if overlap:
                raise overlap

    def _starting_accelerations(self, how: str) -> None:
        """The integrator's start (StartingState.acceleration) on the problem; "zero"
        needs accelerations (rotation vectors: generalized-alpha starts from them)."""
        if isinstance(self.problem, SecondOrderProblem):
            self.problem.starting_accelerations = how
        elif how != "balance":
            raise ValueError(f"start.acceleration = {how!r}: a rod with quaternion unknowns "
                             "has no starting accelerations (its schemes start from the "
                             "state alone); use rotation vectors (rotations='auto')")

    def diagnostics(self, t: float) -> dict[str, float]:
        """MPI-reduced scalars at time t: tip position and quaternion, tip rotation angle
        (of the rotation path, in [0, 2 pi]), the position at each point s of the
        point loads (point{j}_position_{xyz}), free and kinetic energy, dissipation rate
        (incl. drag), power of the applied loads and of the reactions at ends with a
        prescribed motion (load_power; the latter also alone as reaction_power),
        reactions at supported ends; dynamic: momentum_{xyz}, angular_momentum_{xyz}
        (diagnostics.momentum_forms)."""
        d = self.assembled_diagnostics(t)
        d.update(self.tips[-1]())        # a rod split at its kinks: of its last piece
        d.update(self.point_positions())
        d.update(self.supports.reactions(self.residual, t, self.problem.structure))
        if self.kinked:                  # the right end's reactions, of its last piece;
            right = self.end_supports[-1].reactions(self.residual, t, self.problem.structure)
            d["reaction_power"] = d.get("reaction_power", 0.0) + right.pop(
                "reaction_power", 0.0)
            d.update(right)
            d.update(self.joint_reactions())     # the corners' (joint_rod-corner1_force_x)
        d["load_power"] += d.get("reaction_power", 0.0)   # work done by moving ends
        d["tip_rotation_angle"] = diagnostics.tip_rotation_angle(d)
        self.pass_through(t)
        self.contact_diagnostics(d)
        return d

    def contact_diagnostics(self, d: dict) -> None:
        """The obstacles' smallest gap and the segment pairs' energy (into
        contact_energy), total force, smallest gap and count, into d."""
        if self.contact:
            d["min_gap"] = self.contact.closest()[0]
        if self.obstacle_segments:
            segments = self.obstacle_segments.diagnostics()
            d["min_gap"] = min(d["min_gap"], segments.pop("min_gap"))
            d["dissipation_rate"] += segments.get("friction_dissipation", 0.0)
            for key, value in segments.items():
                d[key] = d.get(key, 0.0) + value
            self._update_field(self.segment_force, self.obstacle_segments)
        if self.segment_contact:
            pairs = self.segment_contact.diagnostics()
            d["contact_energy"] = d.get("contact_energy", 0.0) + pairs.pop(
                "pair_contact_energy")
            if "pair_friction_dissipation" in pairs:      # pair_friction.py
                friction = pairs.pop("pair_friction_dissipation")
                d["dissipation_rate"] += friction
                d["friction_dissipation"] = d.get("friction_dissipation", 0.0) + friction
            d.update(pairs)
            self._update_field(self.pair_force, self.segment_contact)
            if self.layout.single and self.segment_contact.self_contact and (
                    self.rods[0].closed or self.supports.ends == ("clamped", "clamped")):
                d["twist"], d["writhe"] = self._twist_and_writhe()

    def _twist_and_writhe(self) -> tuple[float, float]:
        """Tw of the rod's ribbon (d_1 at the nodes) and Wr of its centre line: a ring's
        (ring.ring_linking), else closed along the clamped ends' tangents
        (linking.clamped_rod_linking)."""
        line = self.segment_contact.line
        order = np.argsort(line.reference[:, 2])
        points = line.positions(self.segment_contact.owned_displacement())[order]
        chart = self.unknowns.chart         # the nodal rotations (committed: theta = 0)
        q_n = chart.q_n if chart is not None else self.unknowns.f["quaternion"]
        q = line.gather(q_n.x.array.reshape(-1, 4)[: line.n_owned])[order]
        q /= np.linalg.norm(q, axis=1)[:, None]         # (quaternions: off the unit sphere)
        R = np.stack([np_rotation_matrix(qk) for qk in q])
        if self.rods[0].closed:
            return ring.ring_linking(points, R[:, :, 0])
        return clamped_rod_linking(points, R[:, :, 0], R[0, :, 2], R[-1, :, 2])

    @staticmethod
    def _update_field(f, contact) -> None:
        """A segment contact's force per unit length at the nodes into the P1 field f
        (pair_force, segment_force)."""
        n = f.function_space.dofmap.index_map.size_local
        f.x.array[: 3 * n] = contact.force_density().ravel()
        f.x.scatter_forward()

    def observables(self) -> dict:
        """What a mechanician reads, as UFL expressions of the current state and rates:
        centre line r = X + x (X = s e_3), directors d_i = R e_i, strains u, v, natural
        strains u_d, v_d, reference strains u_ref, v_ref, contact force n and couple m in
        material (``n``, ``m``) and spatial (``n_spatial`` = R n, ``m_spatial`` = R m)
        components, dissipation rate xi (eq. disspw).  Used by the run outputs."""
        q, x = self.unknowns.q, self.f["displacement"]
        s = ufl.SpatialCoordinate(self.mesh)[0]
        R = rotation_matrix(q)
        u_ref, v_ref = self.reference
        n = self.n if self.n is not None else ufl.as_vector((0.0, 0.0, 0.0))
        v_d = self.v_d if self.v_d is not None and ufl.shape(self.v_d) == (3,) else v_ref
        out = {"centre_line": ufl.as_vector((0.0, 0.0, s)) + x}
        out.update({f"d{i + 1}": ufl.as_vector([R[j, i] for j in range(3)]) for i in range(3)})
        out.update({"u": self.u, "v": self.v, "u_d": self.u_d, "v_d": v_d, "u_ref": u_ref,
                    "v_ref": v_ref, "n": n, "m": self.m, "n_spatial": ufl.dot(R, n),
                    "m_spatial": ufl.dot(R, self.m), "xi": self.xi})
        if self.contact:
            out["contact_force"] = self.contact.force_observable()
        if self.segment_contact:
            out["contact_force"] = out.get("contact_force", 0) + self.pair_force
        if self.obstacle_segments:
            out["contact_force"] = out["contact_force"] + self.segment_force
        return out
