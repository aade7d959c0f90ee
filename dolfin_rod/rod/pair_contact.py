"""Contact between the rod's own segments and between rods (issue 26; docs/contact.md):
the segments are capsules of the rod's radius r, two non-neighbouring segments i, j at
the distance d of their centre lines (segments.closest_points) have the gap g = d - 2r,
and the pair carries the energy

    E_ij = kappa w_ij b(g),   w_ij = (h_i + h_j) / 2,

with the barrier b of the obstacles (contact.py; 0 for g >= delta), kappa the stiffness
per unit length and h the cells' reference lengths.  Neighbours along a rod (midpoints
closer in s than the exclusion pi (r + delta) + h) are no pair: a rod whose curvature
stays below 1 / (r + delta) keeps such points farther than 2 r + delta apart.

The residual gets dE/dX at the pair's four nodes, the Jacobian its Hessian: d(X) is the
value of min |p(s) - q(t)| over the parameter square, so (envelope theorem) its
gradient is that at fixed (s, t), and its Hessian f_XX - f_Xa f_aa^-1 f_aX over the
parameters a that are free (inside (0, 1)) (the Hessian of a value function).  The
pairs are found anew at every evaluation (broad phase: a cKDTree, segments.near_pairs),
on every rank from the gathered centre line (3 numbers per node); each rank adds the
rows of the nodes it owns (the columns may belong to any rank).

Newton's updates are shortened (``limit_step``, PETSc's line-search pre-check) so that
no pair's gap falls below a tenth of its value along the update (``step_fraction``: the
straight path of the nodes, on which d is Lipschitz in the path's parameter with the
pair's largest node displacements; bisected where the bound cannot exclude it).  A
step is accepted only if every pair's gap is > 0 at its end and no two segments crossed
on the straight path from the last accepted state (``crossed``, the same bound).

With ``contact.pair_curve = "smooth"`` the pairs' distance is that of C^1 curves through
the nodes (smooth_pairs.py: eight stencil nodes per pair, each close approach counted
once); the searches, checks and bounds above then use the curves' distance.

Coulomb friction of the pairs (``contact.self_friction``, ``between_rods_friction``):
pair_friction.py, with the pairs and normal forces lagged at each accepted state
(``commit``) and the nodes' velocities of the step's affine rate map (``set_rates``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from petsc4py import PETSc

from .barrier import XI_MIN, barrier_derivatives
from .pair_friction import PairFriction
from .segments import PairOverlap, closest_points, exclusion, joint_distances, near_pairs
from .smooth_pairs import LIPSCHITZ, Stencils, closest, counted, free, smooth_pair_energy

CROSSING_DEPTH = 24     # bisections of a step's path before a pair counts as crossed
STEP_FLOOR = 0.1        # a Newton update keeps every pair's gap above this share of its gap
ROUND_OFF = 1e-9        # relative margin of the path check's bound (``first_too_near``)


def pair_energy(X, radius: float, gap: float, stiffness, weights, order: int = 2,
                closest=None):
    """Energy (m,), gradient (m, 12) and (order 2) Hessian (m, 12, 12) of segment pairs
    X (m, 4, 3) = (p0, p1, q0, q1) with weights w_ij (m,): E = kappa w b(d - 2 r), d the
    centre-line distance.  With D = p(s) - q(t) = sum_k w_k X_k at the closest points,
    w = (1 - s, s, t - 1, -t), the gradient of d is w (x) D / d (envelope theorem).
    ``closest``: the pairs' (s, t, d) if known (segments.closest_points of X: the pair
    search's, SegmentContact.near)."""
    p0, p1, q0, q1 = (X[:, k] for k in range(4))
    s, t, d = closest_points(p0, p1, q0, q1) if closest is None else closest
    d1, d2 = p1 - p0, q1 - q0
    D = p0 + s[:, None] * d1 - q0 - t[:, None] * d2
    w = np.stack([1 - s, s, t - 1, -t], axis=1)
    grad = (w[:, :, None] * (D / d[:, None])[:, None, :]).reshape(-1, 12)
    b, b1, b2 = barrier_derivatives(d - 2 * radius, gap)
    k = stiffness * np.asarray(weights, float)
    E, G = k * b, (k * b1)[:, None] * grad
    if order < 2:
        return E, G, None
    return E, G, _pair_hessian(k * b1, k * b2, d, grad, w, D, d1, d2, s, t)


def _pair_hessian(e1, e2, d, grad, w, D, d1, d2, s, t):
    """e1 hess d + e2 grad d grad d^T (e1, e2: the energy's first and second derivatives
    in d), (m, 12, 12).  d^2 is the value of f = |sum_k w_k X_k|^2 minimised over the
    free parameters a of (s, t) (those inside (0, 1)), so its Hessian is f_XX - f_Xa
    f_aa^-1 f_aX (a value function's Hessian), with f_XX = 2 (w w^T) (x) I, f_Xs =
    2 (DS (x) D + w (x) d1), f_Xt = 2 (DT (x) D - w (x) d2) (DS = dw/ds, DT = dw/dt), f_aa = 2 [[a, -b], [-b, e]];
    and hess d = (hess d^2 - 2 grad d grad d^T) / (2 d).  The sum is U^T C U with the
    six rows U = (grad d, f_Xs, f_Xt, w (x) e_1, w (x) e_2, w (x) e_3): one batched
    product of (12 x 6) by (6 x 12) matrices."""
    m = len(d)
    gamma = e1 / (2 * d)
    ss, st, tt = _free_inverse(d1, d2, s, t)
    U = np.zeros((m, 6, 4, 3))
    U[:, 0] = grad.reshape(m, 4, 3)
    U[:, 1] = (2 * w)[:, :, None] * d1[:, None, :]
    U[:, 2] = (-2 * w)[:, :, None] * d2[:, None, :]
    for row, k, sign in ((1, 0, -2), (1, 1, 2), (2, 2, 2), (2, 3, -2)):
        U[:, row, k] += sign * D        # DS = (-1, 1, 0, 0), DT = (0, 0, 1, -1)
    for i in range(3):
        U[:, 3 + i, :, i] = w
    U = U.reshape(m, 6, 12)
    CU = np.empty_like(U)
    CU[:, 0] = (e2 - 2 * gamma)[:, None] * U[:, 0]
    CU[:, 1] = -gamma[:, None] * (ss[:, None] * U[:, 1] + st[:, None] * U[:, 2])
    CU[:, 2] = -gamma[:, None] * (st[:, None] * U[:, 1] + tt[:, None] * U[:, 2])
    CU[:, 3:] = (2 * gamma)[:, None, None] * U[:, 3:]
    return np.matmul(np.transpose(U, (0, 2, 1)), CU)


def _free_inverse(d1, d2, s, t):
    """The entries (ss, st, tt) of f_aa^-1, f_aa = 2 [[a, -b], [-b, e]] (a = d1.d1,
    b = d1.d2, e = d2.d2), on the free parameters (those inside (0, 1)); 0 elsewhere."""
    a, b, e = (np.einsum("ij,ij->i", u, v) for u, v in ((d1, d1), (d1, d2), (d2, d2)))
    free_s, free_t = (s > 0) & (s < 1), (t > 0) & (t < 1)
    both = free_s & free_t
    det = 2 * np.where(both, a * e - b * b, 1.0)
    only_s, only_t = free_s & ~both, free_t & ~both
    ss = np.where(both, e / det, np.where(only_s, 0.5 / np.where(only_s, a, 1.0), 0.0))
    tt = np.where(both, a / det, np.where(only_t, 0.5 / np.where(only_t, e, 1.0), 0.0))
    return ss, np.where(both, b / det, 0.0), tt


class Centreline:
    """The centre line of every rod of a model as segments, known on every rank: the
    global node of each segment end, its reference length, midpoint s and rod; the nodes'
    positions gathered from their owners (X = s e_3 + x)."""

    def __init__(self, x, rod_of):
        space = x.function_space
        self.x, self.comm = x, space.mesh.comm
        imap = space.dofmap.index_map
        self.n_owned = imap.size_local
        n_cells = space.mesh.topology.index_map(1).size_local
        local = space.dofmap.list[:n_cells]
        self.owned_global = imap.local_to_global(np.arange(self.n_owned, dtype=np.int32))
        s = space.tabulate_dof_coordinates()[:, 0]
        cells = np.column_stack([imap.local_to_global(local.ravel()).reshape(-1, 2),
                                 s[local]])
        cells = np.vstack(self.comm.allgather(cells))
        cells = cells[np.argsort(cells[:, 2] + cells[:, 3], kind="stable")]
        self.ends = cells[:, :2].astype(np.int64)                  # global nodes
        self.lengths = np.abs(cells[:, 3] - cells[:, 2])
        self.mid_s = 0.5 * (cells[:, 2] + cells[:, 3])
        self.rod = rod_of(self.mid_s)
        nodes = np.concatenate(self.comm.allgather(self.owned_global))
        self.n_nodes = len(nodes)
        s_all = np.concatenate(self.comm.allgather(s[: self.n_owned]))
        self.reference = np.zeros((self.n_nodes, 3))
        self.reference[nodes, 2] = s_all
        self.gathered = nodes

    def positions(self, owned_displacement: np.ndarray) -> np.ndarray:
        """(nodes, 3) positions of all nodes from each rank's owned displacements."""
        return self.reference + self.gather(owned_displacement.reshape(-1, 3))

    def gather(self, owned: np.ndarray) -> np.ndarray:
        """(nodes, k) values of a P1 field (k components) from each rank's owned ones."""
        out = np.empty((self.n_nodes, owned.shape[1]))
        out[self.gathered] = np.concatenate(self.comm.allgather(owned))
        return out


class NodeRates:
    """The nodes' velocities of a term on the gathered centre line ``line`` (friction:
    the segment pairs', the segments' on obstacles): ``velocity_field`` (P1, the rate of
    x) or the step's affine maps (``set_rates``) of the model's displacement ``block``."""

    velocity_field, rates, block = None, None, 0

    def set_rates(self, maps) -> None:
        """The step's rates as affine maps of the unknowns, per block (slope, intercept):
        rate = slope y + intercept (the integrator's, before a step's solve), or None (the
        rate fields as they are: the start's solves, after the step)."""
        self.rates = None if maps is None else maps[self.block]

    def velocities(self, owned_displacement: np.ndarray) -> np.ndarray:
        """(nodes, 3) the nodes' velocities at the displacement (owned) of a solve."""
        n = 3 * self.line.n_owned
        if self.rates is None:
            owned = self.velocity_field.x.array[:n]
        else:
            slope, intercept = self.rates
            owned = slope * owned_displacement + intercept[:n]
        return self.line.gather(owned.reshape(-1, 3))


class SegmentContact(NodeRates):
    """Self-contact (pairs within a rod) and contact between rods (``between_rods``) of
    the segments of ``x`` (the rod's displacement, P1), a term that fem/assembly adds to
    the residual and Jacobian of the systems that hold x (``bind``); law: the contact
    law (radius, gap, stiffness; friction coefficients and slip tolerance: with
    ``velocity``, x's rate, the pairs' Coulomb friction, pair_friction.py); joints: the
    nodes (s_a, s_b) of the rods' joints; ``along``: the user's rod and the arc length
    on it of parameter values s (layout.RodLayout.along: the pieces of a rod split at
    its kinks are one rod, whose self-contact pairs them; default: each rod of
    ``rod_of`` its own, s its arc length)."""

    def __init__(self, x, law, rod_of, self_contact: bool, between_rods: bool,
                 joints=(), velocity=None, along=None):
        self.x, self.law = x, law
        self.line = Centreline(x, rod_of)
        self.owner, self.arc = ((self.line.rod, self.line.mid_s) if along is None
                                else along(self.line.mid_s))
        mu = (law.self_friction * self_contact, law.between_rods_friction * between_rods)
        # the pairs' curves: the segments, or the C^1 curves of smooth_pairs.py
        self.stencils = (Stencils(self.line.ends, self.line.rod)
                         if law.pair_curve == "smooth" else None)
        if self.stencils is not None and velocity is not None and max(mu) > 0:
            raise ValueError("contact.pair_curve = 'smooth' has no friction between "
                             "segments yet: set contact.self_friction and "
                             "contact.between_rods_friction to 0 or pair_curve to "
                             "'segments'")
        self.friction = (PairFriction(self.line, law, *mu, owner=self.owner)
                         if velocity is not None and max(mu) > 0 else None)
        self.velocity_field, self.rates = velocity, None
        h = float(np.max(self.line.lengths))
        self.exclusion = exclusion(law.radius, law.gap, h)
        # each segment's arc length on its rod, the rods laid apart by more than the
        # exclusion: the broad phase's exclusion in s is then that of ``allowed``
        self.apart = self.arc + self.owner * (self.arc.max(initial=0.0) + self.exclusion + 1.0)
        self.through_joints = self._joint_distances(joints)
        self.self_contact, self.between_rods = self_contact, between_rods
        self.reach = 2 * law.radius + law.gap       # pairs act below this distance
        self.skin = law.radius / 2                   # the candidate list's margin
        self._candidates = (None, 0.0, None)         # positions, distance, pairs
        self._cache = (None, None)
        self.start = None                            # positions at the last commit
        self.block = 0          # the displacement's block in the problem (model sets it)
        self.rod_names = ("rod",)   # the user's rods' (the model sets them: layout.rods)

    # -- pairs and their terms ----------------------------------------------------------

    def pairs(self, P: np.ndarray, distance: float | None = None) -> np.ndarray:
        """(m, 2) segment pairs i < j of positions P whose centre lines are nearer than
        ``distance`` (default the barrier's reach), filtered by self/between rods, in
        lexicographic order: the pairs of the candidate list (``candidates``) that are
        that near."""
        return self.near(P, distance)[0]

    def near(self, P: np.ndarray, distance: float | None = None):
        """:meth:`pairs` and their closest points (s, t, d) (segments.closest_points),
        computed once for the search and the pairs' terms (elementwise: the same bits)."""
        distance = self.reach if distance is None else distance
        if self.stencils is not None:       # a curve lies within its bound of its chord
            candidates = self.candidates(P, distance + 2 * self.stencils.deviation(P).max(
                initial=0.0))
            closest_ = self.curve_closest(P, candidates)
        else:
            candidates = self.candidates(P, distance)
            X = P[self.line.ends[candidates].reshape(-1, 4)]
            closest_ = closest_points(X[:, 0], X[:, 1], X[:, 2], X[:, 3])
        keep = closest_[2] < distance
        return candidates[keep], tuple(v[keep] for v in closest_)

    def curve_closest(self, P: np.ndarray, pairs: np.ndarray):
        """(s, t, d, sigma_s, sigma_t) of the pairs' C^1 curves (smooth_pairs.closest,
        from the segments' closest points)."""
        return self._curve_closest(P[self.pair_nodes(pairs)], pairs)

    def _curve_closest(self, Y, pairs):
        """curve_closest of pairs whose stencil nodes are at Y (m, 8, 3); the segments
        are the stencils' middle nodes."""
        s, t, _ = closest_points(Y[:, 1], Y[:, 2], Y[:, 5], Y[:, 6])
        return closest(Y, *self._curve_weights(pairs), s, t)

    def _curve_weights(self, pairs):
        st = self.stencils
        return ((lambda rows, u: st.weights(pairs[rows, 0], u)),
                (lambda rows, u: st.weights(pairs[rows, 1], u)))

    def pair_nodes(self, pairs: np.ndarray) -> np.ndarray:
        """(m, 4) the pairs' segments' nodes, or (m, 8) their curves' stencil nodes."""
        nodes = self.line.ends if self.stencils is None else self.stencils.nodes
        return nodes[pairs].reshape(len(pairs), 2 * nodes.shape[1])

    def candidates(self, P: np.ndarray, distance: float) -> np.ndarray:
        """A superset of the pairs nearer than ``distance`` at P (a Verlet list): the
        pairs nearer than D = distance + skin at the positions P_c of the last tree
        search, kept while every node stays within (D - distance) / 2 of P_c (a pair's
        distance changes by at most the sum of its two segments' largest node
        displacements); else searched anew (segments.near_pairs: a cKDTree)."""
        P_c, reach, pairs = self._candidates
        if P_c is not None and distance <= reach <= distance + 2 * self.skin and \
                2 * np.sqrt(np.max(np.einsum("ij,ij->i", P - P_c, P - P_c))) <= \
                reach - distance:
            return pairs
        line = self.line
        reach = distance + self.skin
        # the exclusion in s applies within a rod: other rods are laid farther apart
        # (``apart``), so the s test never removes them
        pairs = near_pairs(P[line.ends[:, 0]], P[line.ends[:, 1]], self.apart, reach,
                           self.exclusion)
        pairs = pairs[self.allowed(pairs[:, 0], pairs[:, 1])]
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        self._candidates = (P.copy(), reach, pairs)
        return pairs

    def allowed(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Whether segments i, j (>= 0) make a pair: of one rod (a rod split at its kinks:
        any of its pieces) and not neighbours (closer along it than the exclusion) with
        self-contact, of different rods with between_rods, and not neighbours through a
        joint."""
        same = self.owner[i] == self.owner[j]
        keep = (same & self.self_contact & (np.abs(self.arc[i] - self.arc[j])
                                            >= self.exclusion)) | (~same & self.between_rods)
        for near in self.through_joints:        # neighbours through a joint
            keep &= near[i] + near[j] >= self.exclusion
        return keep

    def _counted_pairs(self, pairs, closest_):
        """The pairs whose curves' minimiser is theirs (smooth_pairs.counted: the
        neighbouring pair across an edge of the square is a pair too), their closest
        points and which of (s, t) are free (smooth_pairs.free)."""
        st = self.stencils
        keep = np.ones(len(pairs), bool)
        free_ = []
        for col in (0, 1):
            seg, other = pairs[:, col], pairs[:, 1 - col]
            side = [(n >= 0) & self.allowed(np.maximum(n, 0), other)
                    for n in (st.prev[seg], st.next[seg])]
            keep &= counted(closest_[3 + col], *side)
            free_.append(free(closest_[col], *side))
        return pairs[keep], tuple(v[keep] for v in closest_), np.array(free_)[:, keep]

    def _joint_distances(self, joints) -> list[np.ndarray]:
        """segments.joint_distances of the segments' midpoints."""
        return joint_distances(self.line.mid_s, joints)

    def evaluate(self, owned_displacement: np.ndarray) -> "PairTerms":
        """The active pairs at this state and their energies, gradients, Hessians
        (collective; kept for the Jacobian at the same state)."""
        P = self.line.positions(owned_displacement)
        key, value = self._cache
        if key is not None and np.array_equal(key, P):
            return value
        pairs, closest_ = self.near(P)
        law = self.law
        if self.stencils is not None:
            pairs, closest_, free_ = self._counted_pairs(pairs, closest_)
            nodes = self.pair_nodes(pairs)
            energy = smooth_pair_energy(
                P[nodes].reshape(-1, 8, 3), *self._curve_weights(pairs), *closest_[:2],
                free_, law.radius, law.gap, law.stiffness, 0.5 * self.line.lengths[pairs].sum(axis=1))
        else:
            nodes = self.pair_nodes(pairs)
            energy = pair_energy(P[nodes].reshape(-1, 4, 3), law.radius, law.gap,
                                 law.stiffness, 0.5 * self.line.lengths[pairs].sum(axis=1),
                                 closest=closest_)
        value = PairTerms(pairs, nodes, *energy)
        self._cache = (P, value)
        return value

    def forget(self) -> None:
        """The next :meth:`evaluate` computes the pairs' terms anew even at the same
        state (the cost of a new state near the last one,
        benchmarks/contact_assembly.py)."""
        self._cache = (None, None)

    def forget_candidates(self) -> None:
        """The next pair search builds its tree anew (benchmarks/contact_assembly.py)."""
        self._candidates = (None, 0.0, None)

    def owned_displacement(self) -> np.ndarray:
        return self.x.x.array[: 3 * self.line.n_owned]

    def for_step(self, stages, fields, previous, before_previous) -> "StepTerm":
        """The term in a per-step scheme's residual sum_k w_k F(Y_k, ...) (stages: (w_k,
        (a0, a1, a2)) with Y_k = a0 y + a1 y_n + a2 y_{n-1}; fields, previous,
        before_previous: the problem's unknowns y and their y_n, y_{n-1})."""
        block = next(k for k, y in enumerate(fields) if y is self.x)
        return StepTerm(self, stages, previous[block], before_previous[block])

    def bind(self, system, step: "StepTerm | None" = None) -> "BoundTerm":
        """The term in an assembled ``system`` (fem/assembly) one of whose unknowns is x
        (any block: the tangent stiffness of analysis/ holds the mechanical blocks only),
        or whose block ``self.block`` (the model's displacement block) holds another
        unknown of its space (the start's accelerations: then x is fixed and the term
        adds its residual only); with ``step``, a per-step scheme's stages."""
        return BoundTerm(self, system, step)

    # -- diagnostics ------------------------------------------------------------------

    def diagnostics(self) -> dict[str, float]:
        """Pair energy, the sum of the pair forces' magnitudes, the smallest pair gap
        (capped at the barrier's gap delta: farther pairs are not searched) and the
        count of pairs within the barrier's reach, of the current state."""
        terms = self.evaluate(self.owned_displacement())
        P = self.line.positions(self.owned_displacement())
        gaps = self._gaps(P, terms.pairs)
        G = terms.gradient
        out = {"pair_contact_energy": float(terms.energy.sum()),
               "pair_contact_force": float(np.linalg.norm(
                   G[:, :G.shape[1] // 2].reshape(len(G), G.shape[1] // 6, 3).sum(1),
                   axis=1).sum()),
               "min_pair_gap": float(gaps.min(initial=self.law.gap)),
               "contact_pairs": float(len(gaps))}
        if self.friction is not None:       # of the force the last step applied (commit)
            out["pair_friction_dissipation"] = self.friction.dissipation
            out["pair_friction_force"] = self.friction.force
        return out

    def _gaps(self, P, pairs):
        return self._distances(P, pairs) - 2 * self.law.radius

    def _distances(self, P, pairs):
        """The pairs' centre-line distances at P: of their segments or (smooth) curves."""
        return self._pair_distances(P[self.pair_nodes(pairs)], pairs)

    def _pair_distances(self, Y, pairs):
        """The distances of pairs whose nodes (``pair_nodes``) are at Y (m, 4 | 8, 3)."""
        if self.stencils is None:
            return closest_points(Y[:, 0], Y[:, 1], Y[:, 2], Y[:, 3])[2]
        return self._curve_closest(Y, pairs)[2]

    def force_density(self) -> np.ndarray:
        """(owned nodes, 3) the pairs' contact force per unit length at the owned nodes
        (the nodes' forces over their share of the reference length, h/2 per cell)."""
        return nodal_force_density(self.line, self.evaluate(self.owned_displacement()))

    # -- the step's checks ------------------------------------------------------------

    def commit(self) -> None:
        """After an accepted step: its positions start the next step's crossing check;
        friction: the power of the force the step applied (its lagged pairs, the step's
        velocities), then the pairs lagged anew at this state."""
        self.start = self.line.positions(self.owned_displacement())
        if self.friction is not None:
            friction = self.friction
            friction.dissipation, friction.force = friction.power(
                self.velocities(self.owned_displacement()))
            friction.lag(self.start, self.pairs(self.start))

    def check_state(self) -> str | None:
        """A reason to reject a converged step: a pair at gap <= 0, or two segments that
        crossed on the straight path from the last committed state."""
        end = self.line.positions(self.owned_displacement())
        pairs = self.pairs(end)
        gaps = self._gaps(end, pairs)
        if len(gaps) and gaps.min() <= 0:
            k = int(np.argmin(gaps))
            return self._where(pairs[k], f"overlap by {-gaps[k]:.3g} (the barrier was "
                                         "overcome: raise contact.stiffness)")
        if self.start is None:
            return None
        crossed = self.crossed(self.start, end)
        return None if crossed is None else self._where(crossed, "passed through each "
                                                        "other during the step")

    def initial_overlap(self) -> PairOverlap | None:
        """At t = 0: the pair with the smallest gap if it is <= 0 (the error of a start
        with overlapping segments, naming contact.self or contact.between_rods)."""
        P = self.line.positions(self.owned_displacement())
        pairs = self.pairs(P)
        gaps = self._gaps(P, pairs)
        if not len(gaps) or gaps.min() > 0:
            return None
        k = int(np.argmin(gaps))
        names, point = self._named(pairs[k], P)
        return PairOverlap.at(names, point, float(gaps[k]), self.law.radius,
                              self.owner[pairs[k][0]] == self.owner[pairs[k][1]])

    def _where(self, pair, what: str, P: np.ndarray | None = None) -> str:
        """The pair's segments named by rod and arc length (their midpoints), the point
        between their closest points at positions P (default the current state), and
        ``what``."""
        names, point = self._named(pair, P)
        return (f"segments of {names[0]} and {names[1]}, near ("
                f"{', '.join(f'{v:.4g}' for v in point)}): {what}")

    def _named(self, pair, P: np.ndarray | None = None) -> tuple[list[str], np.ndarray]:
        """The names of the pair's segments (``segment_name``) and the point between their
        closest points at positions P (default the current state)."""
        P = self.line.positions(self.owned_displacement()) if P is None else P
        X = P[self.line.ends[np.asarray(pair)].reshape(4)]
        s, t, _ = closest_points(*(X[k][None] for k in range(4)))
        point = 0.5 * (X[0] + s[0] * (X[1] - X[0]) + X[2] + t[0] * (X[3] - X[2]))
        return [self.segment_name(k) for k in pair], point

    def segment_name(self, k: int) -> str:
        """'rod NAME at s = ...' of segment k (its midpoint's arc length on its rod)."""
        name = self.rod_names[int(self.owner[k])]
        return f"{'the rod' if len(self.rod_names) == 1 else f'rod {name}'} at s = " \
               f"{self.arc[k]:.4g}"

    def nearest_pair(self) -> str | None:
        """Where a failed solve was: the pair with the smallest gap at the last state
        evaluated (Newton's last iterate; the current state if that is not finite),
        named by ``_where``; None without a pair within the barrier's reach."""
        P = self._cache[0]
        if P is None or not np.isfinite(P).all():
            P = self.line.positions(self.owned_displacement())
        pairs = self.pairs(P)
        if not len(pairs):
            return None
        gaps = self._gaps(P, pairs)
        k = int(np.argmin(gaps))
        return self._where(pairs[k], f"gap {gaps[k]:.3g} (the barrier acts below "
                                     f"{self.law.gap:g}) at Newton's last iterate", P)

    def crossed(self, P0: np.ndarray, P1: np.ndarray):
        """A pair whose centre lines meet on the straight path P0 -> P1 of the nodes, or
        None (``first_too_near`` with the floor 0)."""
        return self.first_too_near(P0, P1, lambda d0: np.zeros_like(d0))

    def first_too_near(self, P0: np.ndarray, P1: np.ndarray, floor):
        """A pair whose centre-line distance d falls to floor(d(0)) or below on the
        straight path P0 -> P1 of the nodes, or None.  d(tau) changes at most by L =
        (largest displacement of the first segment's nodes + of the second's) per unit
        tau, so on an interval [a, b] with d(a) + d(b) - L (b - a) > 2 floor it stays
        above the floor; other intervals are bisected CROSSING_DEPTH times."""
        move = np.linalg.norm(P1 - P0, axis=1)
        smooth = self.stencils is not None
        e = self.line.ends if not smooth else self.stencils.nodes
        gain = LIPSCHITZ if smooth else 1.0     # a curve point moves <= gain its nodes' most
        pairs = self.pairs(P0, 2 * gain * move.max() + self.reach)
        if not len(pairs):
            return None
        L = gain * (move[e[pairs[:, 0]]].max(1) + move[e[pairs[:, 1]]].max(1))

        def dist(tau, k):
            nodes = self.pair_nodes(pairs[k])
            return self._pair_distances(P0[nodes] + tau[:, None, None] * (P1 - P0)[nodes],
                                        pairs[k])

        idx = np.arange(len(pairs))
        a, b = np.zeros(len(pairs)), np.ones(len(pairs))
        da, db = dist(a, idx), dist(b, idx)
        low = floor(da)
        for _ in range(CROSSING_DEPTH):
            near = np.minimum(da, db) <= low[idx]
            if near.any():
                return pairs[idx[near][0]]
            # with a round-off margin: a segment moved straight through another at the
            # bound's rate has d(a) + d(b) = L (b - a) exactly on the interval of its
            # passage (a V of slope L), which round-off must not close
            open_ = da + db - L[idx] * (b - a) <= 2 * low[idx] + ROUND_OFF * L[idx] * (b - a)
            if not open_.any():
                return None
            idx, a, b, da, db = idx[open_], a[open_], b[open_], da[open_], db[open_]
            m = 0.5 * (a + b)
            dm = dist(m, idx)
            idx, a, b, da, db = (np.concatenate(v) for v in
                                 ((idx, idx), (a, m), (m, b), (da, dm), (dm, db)))
        return pairs[idx[np.argmin(np.minimum(da, db))]]

    def step_fraction(self, P0: np.ndarray, P1: np.ndarray) -> float:
        """The largest 2^-k (k <= CROSSING_DEPTH) such that on the straight path from P0
        towards P1 up to it no pair's gap g falls below STEP_FLOOR of its gap g0 at P0, or
        by more than (1 - STEP_FLOOR) g_min where g0 < g_min (the barrier's Taylor range,
        contact.XI_MIN: the bisection's work grows like the update's length over the
        margin g0 - floor, which must not vanish with g0; docs/contact.md); a pair
        already closer than 2 r: below half its distance."""
        r2 = 2 * self.law.radius
        margin = (1 - STEP_FLOOR) * XI_MIN * self.law.gap

        def floor(d0):
            g0 = d0 - r2
            return np.where(d0 > r2, r2 + np.minimum(STEP_FLOOR * g0, g0 - margin), 0.5 * d0)

        alpha = 1.0
        for _ in range(CROSSING_DEPTH):
            if self.first_too_near(P0, P0 + alpha * (P1 - P0), floor) is None:
                return alpha
            alpha *= 0.5
        return alpha


def nodal_force_density(line: Centreline, terms: "PairTerms") -> np.ndarray:
    """(owned nodes, 3) the terms' contact force per unit length at the owned nodes of
    the centre line (the nodes' forces -dE/dX over their share of the reference length,
    h/2 per cell)."""
    forces = np.zeros((line.n_nodes, 3))
    np.add.at(forces, terms.nodes.ravel(), -terms.gradient.reshape(-1, 3))
    share = np.zeros(line.n_nodes)
    np.add.at(share, line.ends.ravel(), np.repeat(line.lengths / 2, 2))
    owned = line.owned_global
    return forces[owned] / share[owned, None]


class StepTerm:
    """SegmentContact in a per-step scheme's residual (SegmentContact.for_step): stage k
    adds w_k dE/dX(Y_k) to the residual and w_k a0_k H(Y_k) to the Jacobian, Y_k the
    stage's displacement (a0 x + a1 x_n + a2 x_{n-1})."""

    def __init__(self, contact: SegmentContact, stages, previous, before_previous):
        self.contact, self.stages = contact, list(stages)
        self.previous, self.before_previous = previous, before_previous

    def bind(self, system) -> "BoundTerm":
        return self.contact.bind(system, self)

    def states(self, u: np.ndarray) -> list[tuple[float, float, np.ndarray]]:
        """(w_k, a0_k, Y_k) of the stages at the owned displacement u."""
        n = len(u)
        return [(w, a[0], a[0] * u + a[1] * self.previous.x.array[:n]
                 + a[2] * self.before_previous.x.array[:n]) for w, a in self.stages]


class BoundTerm:
    """SegmentContact in one assembled system (fem/assembly): residual rows and Jacobian
    entries of the owned nodes (the system's global row numbers for the columns); with a
    StepTerm ``step``, its stages' sum."""

    def __init__(self, contact: SegmentContact, system, step: StepTerm | None = None):
        self.contact, self.step = contact, step
        line = contact.line
        unknowns = system.groups[0]
        held = [k for k, y in enumerate(unknowns) if y is contact.x]
        self.solved = bool(held)
        block = held[0] if held else contact.block
        self.local_rows = system.rows_of(block, np.arange(3 * line.n_owned))
        start = system.x.getOwnershipRange()[0]
        rows = np.full((line.n_nodes, 3), -1, dtype=np.int64)
        rows[line.gathered] = np.concatenate(line.comm.allgather(
            (self.local_rows + start).reshape(-1, 3)))
        self.global_rows = rows
        self.owned = np.zeros(line.n_nodes, bool)
        self.owned[line.owned_global] = True
        self.row_of_node = np.full(line.n_nodes, -1, dtype=np.int64)
        self.row_of_node[line.owned_global] = np.arange(line.n_owned)
        self.in_pattern = np.zeros(0, dtype=np.int64)    # pairs i * segments + j with
        self._state = None                               # entries in the matrix
        self._friction = None       # the friction's (nodes, G, dR/dV) at the last state

    def add_residual(self, x_owned: np.ndarray, b_owned: np.ndarray) -> None:
        """b += dE/dX at the owned nodes' rows (x: the system's owned unknowns), and the
        friction's -w_k F (pair_friction.py; generalized-alpha's steps only)."""
        contact = self.contact
        u = x_owned[self.local_rows] if self.solved else contact.owned_displacement()
        self._state = [(1.0, 1.0, u)] if self.step is None else self.step.states(u)
        for weight, _, state in self._state:
            terms = contact.evaluate(state)
            self._add_rows(b_owned, terms.nodes, weight * terms.gradient)
        if contact.friction is not None:
            self._friction = contact.friction.residual(contact.velocities(u))
            self._add_rows(b_owned, *self._friction[:2])

    def _add_rows(self, b_owned: np.ndarray, nodes: np.ndarray, G: np.ndarray) -> None:
        """b += the pairs' entries G (m, 12) at the rows of their owned nodes (m, 4)."""
        nodes = nodes.ravel()
        mine = self.owned[nodes]
        rows = self.local_rows.reshape(-1, 3)[self.row_of_node[nodes[mine]]]
        b_owned += np.bincount(rows.ravel(), G.reshape(-1, 3)[mine].ravel(),
                               minlength=len(b_owned))

    def limit_step(self, x_owned: np.ndarray, y_owned: np.ndarray) -> None:
        """Newton's update x - y (PETSc's sign) scaled down in place by ``step_factor``."""
        alpha = self.step_factor(x_owned, y_owned)
        if alpha < 1.0:
            y_owned *= alpha

    def step_factor(self, x_owned: np.ndarray, y_owned: np.ndarray) -> float:
        """The factor of Newton's update x - y (PETSc's sign) after which no pair closes
        to below STEP_FLOOR of its gap along it (SegmentContact.step_fraction;
        collective: the same factor on every rank); 1 if x is not solved for."""
        if not self.solved:
            return 1.0
        u = x_owned[self.local_rows]
        line = self.contact.line
        P0 = line.positions(u)
        return self.contact.step_fraction(P0, line.positions(u - y_owned[self.local_rows]))

    def missing_entries(self):
        """(rows, columns) (global, owned rows) of the Jacobian entries that the pairs at
        the last residual's states need and the system's matrix lacks, or None (the same
        answer on every rank: the pairs are found on the gathered centre line).  With
        them come the entries of the pairs within one more barrier gap delta (the pairs
        that may come next), so that the pattern grows in few, large steps."""
        if not self.solved or self._state is None:
            return None
        contact = self.contact
        n_segments = len(contact.line.ends)
        pairs = np.vstack([contact.evaluate(state).pairs for _, _, state in self._state]
                          + ([contact.friction.pairs] if contact.friction is not None else []))
        keys = pairs[:, 0] * n_segments + pairs[:, 1]
        place = np.searchsorted(self.in_pattern, keys)
        if np.all(place < len(self.in_pattern)) and \
                np.array_equal(self.in_pattern[place], keys):
            return None
        coming = np.vstack([contact.pairs(contact.line.positions(state),
                                          contact.reach + contact.law.gap)
                            for _, _, state in self._state])
        self.in_pattern = np.union1d(self.in_pattern, np.concatenate(
            [keys, coming[:, 0] * n_segments + coming[:, 1]]))
        return self._entries(np.vstack([pairs, coming]))

    def _entries(self, pairs):
        """(rows, columns) of the 3 x 3 blocks of every two nodes of each pair's nodes
        (``pair_nodes``), rows of owned nodes only."""
        n_nodes = self.contact.line.n_nodes
        nodes = self.contact.pair_nodes(pairs)
        keys = np.unique((nodes[:, :, None] * n_nodes + nodes[:, None, :]).ravel())
        a, b = keys // n_nodes, keys % n_nodes
        a, b = a[self.owned[a]], b[self.owned[a]]
        rows, cols = self.global_rows[a], self.global_rows[b]
        return (np.repeat(rows, 3, axis=1).ravel(),
                np.broadcast_to(cols[:, None, :], (len(a), 3, 3)).ravel())

    def add_jacobian(self, A) -> None:
        """A += the pairs' Hessians (rows of owned nodes) at the last residual's state
        (into entries the system added for ``missing_entries``), and the friction's
        dR/dV times the rates' slope dV/dx."""
        if not self.solved or self._state is None:
            return
        for weight, a0, state in self._state:
            terms = self.contact.evaluate(state)
            if weight * a0 != 0.0:
                self._add_matrix(A, terms.nodes, weight * a0 * terms.hessian)
        rates = self.contact.rates
        if self.contact.friction is not None and rates is not None:
            nodes, _, H = self._friction
            self._add_matrix(A, nodes, rates[0] * H)

    def _add_matrix(self, A, nodes: np.ndarray, H: np.ndarray) -> None:
        """A += the blocks H (3k x 3k) of the pairs' k nodes (rows of owned nodes)."""
        if not len(nodes):
            return
        rows = self.global_rows[nodes].reshape(len(nodes), -1)
        owned = np.repeat(self.owned[nodes].reshape(len(nodes), -1), 3, axis=1)
        # one call for all pairs (PETSc's loop); other ranks' rows as -1: skipped
        A.setValuesRCV(np.where(owned, rows, -1).astype(PETSc.IntType),
                       rows.astype(PETSc.IntType), H, addv=PETSc.InsertMode.ADD_VALUES)


class PairTerms(NamedTuple):
    """The active pairs (m, 2) of segments, their nodes (m, k) (global numbers: k = 4,
    or 8 for smooth pairs' stencils), and their energies (m,), gradients (m, 3k) and
    Hessians (m, 3k, 3k)."""
    pairs: np.ndarray
    nodes: np.ndarray
    energy: np.ndarray
    gradient: np.ndarray
    hessian: np.ndarray
