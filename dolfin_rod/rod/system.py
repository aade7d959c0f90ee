"""Several rods in one model: ``RodSystem``.

Each rod (rods.Rod) has its own length, cells, material and reference strains, ends,
end motions and loads, and its place in space (position, orientation); the rods share
the constitutive model, the evolution variant, the constraint and the rotation
unknowns.  They live on one interval mesh with one component per rod (layout.py), so
the whole system is one SemiDiscreteProblem: one residual, one Jacobian, one Newton
per step for all rods, advanced by any integrator of a single rod.  Rods without joints
are independent: the system's Jacobian is block diagonal, one block per rod, and each
rod's motion equals its run alone to round-off (tests/test_rod_system.py).

    rods = [Rod(params, n_cells=16, position=(0.1 * k, 0, 0), name=f"rod{k}",
                end_loads=[EndLoad("force", (0, 1e-3, 0))]) for k in range(6)]
    system = RodSystem(rods)
    system.set_initial_state()
    TimeStepper(system.problem).run(0.0, 1.0, 0.01)
    system.diagnostics(t)   # totals (energies, powers) and per rod "rod0.tip_position_x"

Joints (joints.py: rigid, ball) tie a node of one rod to a node of another exactly
(fem/multipoint.py: Newton on the free dofs); their reactions are in the diagnostics.

Per rod the cells and nodes are those of its parameter range ``layout.span(k)``
(``layout.rod_of_cells(mesh)``: the rod of every local cell).
"""

from __future__ import annotations

from typing import Sequence

from mpi4py import MPI

from ..checks import ROD_MODEL, ROTATION_UNKNOWNS, VARIANT, old_keywords
from . import diagnostics
from .model import RodModel
from .contact import ContactLaw, Obstacle
from .joints import Joint
from .rods import OLD_CONSTRAINT, Rod, new_keywords


class RodSystem(RodModel):
    """Several rods (rods.Rod) in one model, joined by ``joints`` (joints.Joint); model,
    variant, constraints, rotations, obstacles and contact as RodModel (common to all
    rods).  A rod whose stress-free polyline has corners is split there into pieces
    joined rigidly (kinks.py; the joints naming it attach to the piece at their point).
    Diagnostics: the system's energies and powers under the single rod's names, each
    rod's tip and reactions as ``<name>.<key>`` (a split rod's: of its last piece, of its
    ends), each joint's reactions as ``joint_<name>_...`` (a corner's:
    ``joint_<rod>-corner<k>_...``)."""

    @old_keywords("RodSystem", OLD_CONSTRAINT, new_keywords)
    def __init__(self, rods: Sequence[Rod], joints: Sequence[Joint] = (),
                 model: str = ROD_MODEL, variant: str = VARIANT,
                 constraints: str | None = None, rotations: str = ROTATION_UNKNOWNS,
                 comm: MPI.Comm = MPI.COMM_WORLD, obstacles: Sequence[Obstacle] = (),
                 contact: ContactLaw | None = None):
        self._build(list(rods), model, variant, constraints, rotations, comm, joints,
                    obstacles=obstacles, contact=contact)

    def diagnostics(self, t: float) -> dict[str, float]:
        """MPI-reduced scalars at time t: free and kinetic energy, dissipation rate, load
        power (with the reactions' power at moving ends) of the whole system; per rod
        ``<name>.tip_position_{xyz}``, ``<name>.tip_quaternion_{0..3}``,
        ``<name>.tip_rotation_angle``, the positions at its point loads' points
        ``<name>.point{j}_position_{xyz}`` and its reactions (RodModel.diagnostics)."""
        d = self.assembled_diagnostics(t)
        moving, reaction_power = False, 0.0
        first = 0
        for split, points in zip(self.splits, self.rod_point_positions):
            last = first + len(split.rods) - 1   # a rod split at its corners: its pieces
            own = self.tips[last]()
            own.update(points())
            for supports in self.end_supports[first:last + 1]:   # (inner ends: free)
                own.update(supports.reactions(self.residual, t, self.problem.structure))
                moving = moving or "reaction_power" in own
                reaction_power += own.pop("reaction_power", 0.0)
            own["tip_rotation_angle"] = diagnostics.tip_rotation_angle(own)
            d.update({f"{split.rods[0].name}.{key}": value for key, value in own.items()})
            first = last + 1
        if self.joint_reactions is not None:
            d.update(self.joint_reactions())
        if moving:
            d["reaction_power"] = reaction_power
            d["load_power"] += reaction_power
        self.pass_through(t)
        self.contact_diagnostics(d)
        return d
