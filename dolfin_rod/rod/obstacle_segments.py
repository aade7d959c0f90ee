"""Contact of the rod's segments with thin obstacles (issue 26; docs/contact.md, "Thin
obstacles"): a sphere or a finite cylinder whose barrier acts on the centre line's
segments, not only at its nodes (contact.on_segments: ``contact = "segments"``, or
"auto" for an obstacle thinner than the nodes can hold).

The obstacle is a fixed segment Q = (q0, q1) of radius R (a cylinder's axis between its
lids' centres; a sphere's centre, q0 = q1): segment i of the rod, P_i = (p0, p1), is at
the distance d_i of the two segments (segments.closest_points) and has the gap
g_i = d_i - R - r; it carries the energy

    E_i = kappa (h_i / 2) b(g_i)

with the obstacles' barrier b (contact.py) and the cell's reference length h_i (a node
on the obstacle then has the nodal law's energy kappa (h_(i-1) + h_i) / 2 b: its two
segments' closest point).  The energy, gradient and Hessian are the segment pairs'
(pair_contact.pair_energy with the obstacle's segment as the second one, radius
(R + r) / 2 for each: d - 2 (R + r) / 2) restricted to the rod's two nodes (the
obstacle's do not move): the value function's exact Hessian.  The cylinder is thus a
capsule (its lids rounded by hemispheres of radius R): exact where the rod touches its
side.  A cell's two nodes are coupled by the rod's own forms, so the Jacobian's pattern
does not grow.

With ``contact.obstacle_curve = "smooth"`` (the default; "segments": the law above) the
barrier acts on the rod's C^1 curve instead (smooth_pairs.py: each cell's Catmull-Rom cubic through its four stencil nodes,
the obstacle's segment a straight second curve): a cell carries kappa w b(d - R - r) of
its curve's closest point only where that minimiser is its own (smooth_pairs.counted:
not its neighbour's along the rod), so a contact counts once wherever it lies, across
nodes too (on the segments a node on the obstacle carries its two cells' energies, a
contact mid-cell one cell's); w is the rod's mean cell length (the same weight wherever
the contact lies).  The gradient and Hessian are in the four stencil nodes (the
Jacobian's pattern grows: ``BoundSegments.missing_entries``); the gaps and the step
check are the curves'.

Coulomb friction (the obstacle's ``friction`` mu): the segment pairs' law
(pair_friction.py) with the obstacle's segment at rest: at each accepted state each
segment within reach is frozen with its closest point s, normal n (from the obstacle's
segment to the rod's) and normal force lambda = -kappa (h / 2) b'(g); in the next step
its nodes carry w_k F, w = (1 - s, s), F = -mu lambda phi(|u| / eps) u / |u|, u the
tangential velocity T ((1 - s) V_0 + s V_1) of its closest point (on the curve: its
Catmull-Rom weights over the four stencil nodes).

Broad phase (``near``): with more than ``ALL_PAIRS`` (cell, obstacle segment) pairs, a
scipy cKDTree of the obstacle segments cut into pieces no longer than the longest cell
(fixed: built once) is searched from a cKDTree of the cells' midpoints (O(N log N));
the pairs it finds within reach + skin are kept as a candidate list (a Verlet list, as
pair_contact's) while no node moved farther than the skin from where the list was built
(the obstacle is fixed and every point of a segment moves by at most its nodes' largest
displacement, so a pair's distance changes by no more).  Fewer pairs are compared all
(no scipy import).  Either way the pairs come out in the order (cell, then obstacle
segment) and their closest points are computed elementwise: the same pairs and bits.
On the curves the broad phase finds the chords within reach plus the curves' largest
deviation from their chords.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .contact import ContactLaw
from .barrier import barrier_derivatives
from .obstacle_shapes import Obstacle, fixed_segments
from .pair_contact import (BoundTerm, Centreline, NodeRates, PairTerms, StepTerm,
                           nodal_force_density, pair_energy)
from .pair_friction import PairFriction
from .segments import closest_points
from .smooth_pairs import Stencils, closest, counted, free, smooth_pair_energy

ALL_PAIRS = 4096    # (cell, obstacle segment) pairs compared all, without a tree
ROUND_OFF = 1e-9    # relative margin of the broad phase's bounds (triangle inequality)


class ObstacleSegments(NodeRates):
    """The segment contact of the rod (displacement ``x``, P1) with ``obstacles`` ((k,
    Obstacle) of the scene's obstacles[k]; their ``fixed_segments`` for the longest cell
    h), a term that fem/assembly adds to the residual and Jacobian of the systems holding
    x (``bind``; pair_contact.BoundTerm's rows)."""

    def __init__(self, x, law: ContactLaw, obstacles: Sequence[tuple[int, Obstacle]],
                 rod_of, h: float, velocity=None):
        self.x, self.law = x, law
        self.line = Centreline(x, rod_of)
        parts = [(k, fixed_segments(ob, law.radius + law.gap, h)) for k, ob in obstacles]
        self.index = np.concatenate([np.full(len(q[2]), k, dtype=np.int64)
                                     for k, q in parts])
        self.q0, self.q1, radius = (np.concatenate([q[j] for _, q in parts])
                                    for j in range(3))
        self.contact_radius = radius + law.radius
        # the rod's curves: its segments, or the C^1 curves of smooth_pairs.py with each
        # close approach counted once (contact.obstacle_curve = "smooth")
        line = self.line
        self.stencils = (Stencils(line.ends, line.rod)
                         if law.obstacle_curve == "smooth" else None)
        rod_mean = np.bincount(line.rod, line.lengths) / np.bincount(line.rod)
        self.weight = 0.5 * line.lengths if self.stencils is None else rod_mean[line.rod]
        mu = np.concatenate([np.full(len(q[2]), ob.friction)
                             for (_, q), (_, ob) in zip(parts, obstacles)])
        directional = np.concatenate([np.tile(
            ob.directional_friction or (ob.friction,) * 3, (len(q[2]), 1))
            for (_, q), (_, ob) in zip(parts, obstacles)]).reshape(-1, 3)
        self.velocity_field = velocity
        self.friction = (ObstacleFriction(self, mu, directional if any(
            ob.directional_friction for _, ob in obstacles) else None)
                         if velocity is not None and mu.max(initial=0.0) > 0 else None)
        self._cache = (None, None)
        self.tree = len(self.line.ends) * len(self.index) > ALL_PAIRS   # the broad phase
        self.skin = law.radius / 2                   # the candidate list's margin
        self._candidates = (None, 0.0, None)         # positions, distance, pairs
        self._pieces = None                          # the obstacle segments' tree

    def owned_displacement(self) -> np.ndarray:
        return self.x.x.array[: 3 * self.line.n_owned]

    def distances(self, P: np.ndarray):
        """(cells, obstacles) arrays s, t, d of each segment's closest points to each
        obstacle's segment at the nodes' positions P (every pair: the reference of the
        broad phase, tests/test_obstacle_segments.py)."""
        line, n = self.line, len(self.index)
        p0, p1 = (np.repeat(P[line.ends[:, j]], n, axis=0) for j in (0, 1))
        q0, q1 = (np.tile(q, (len(line.ends), 1)) for q in (self.q0, self.q1))
        return tuple(v.reshape(-1, n) for v in closest_points(p0, p1, q0, q1))

    def pair_distances(self, P: np.ndarray, cell: np.ndarray, j: np.ndarray):
        """s, t, d of the pairs (cell, j) at positions P (elementwise: the bits of
        ``distances``)."""
        ends = self.line.ends[cell]
        return closest_points(P[ends[:, 0]], P[ends[:, 1]], self.q0[j], self.q1[j])

    def near(self, P: np.ndarray, gap: float):
        """(cell, j, s, t, d) of the pairs whose gap d - (R_j + r) is below ``gap``
        (d < R_j + r + gap) at positions P, in the order (cell, then j): every pair
        compared, or the broad phase's candidates (module docstring)."""
        if not self.tree:
            s, t, d = self.distances(P)
            cell, j = np.nonzero(d < self.contact_radius + gap)
            return cell, j, s[cell, j], t[cell, j], d[cell, j]
        cell, j = self.candidates(P, float(self.contact_radius.max()) + gap)
        s, t, d = self.pair_distances(P, cell, j)
        keep = d < self.contact_radius[j] + gap
        return cell[keep], j[keep], s[keep], t[keep], d[keep]

    def candidates(self, P: np.ndarray, distance: float):
        """(cell, j) a superset of the pairs nearer than ``distance`` at P, in the order
        (cell, then j): those nearer than D = distance + skin at the positions P_c of the
        last search, kept while every node stays within D - distance of P_c (a pair's
        distance changes by at most its segment's largest node displacement: the
        obstacle is fixed); else searched anew (``search``)."""
        P_c, reach, pairs = self._candidates
        if P_c is not None and distance <= reach <= distance + self.skin and \
                np.sqrt(np.max(np.einsum("ij,ij->i", P - P_c, P - P_c))) <= reach - distance:
            return pairs
        reach = distance + self.skin
        cell, j = self.search(P, reach)
        keep = self.pair_distances(P, cell, j)[2] < reach * (1 + ROUND_OFF)  # round-off
        pairs = cell[keep], j[keep]
        self._candidates = (P.copy(), reach, pairs)
        return pairs

    def search(self, P: np.ndarray, distance: float, cells: np.ndarray | None = None):
        """(cell, j) in the order (cell, then j), a superset of the pairs nearer than
        ``distance`` at P (of ``cells``, default all): the obstacle segments' pieces
        (half-length at most l / 2) whose centre is within distance + h / 2 + l / 2 of a
        cell's midpoint (h the longest cell at P): the closest points of a pair lie
        within h / 2 and l / 2 of these."""
        ends = self.line.ends if cells is None else self.line.ends[cells]
        p0, p1 = P[ends[:, 0]], P[ends[:, 1]]
        h = np.sqrt(np.max(np.einsum("ij,ij->i", p1 - p0, p1 - p0), initial=0.0))
        tree, piece_of, half = self.pieces()
        from scipy.spatial import cKDTree       # imported only with the broad phase
        found = cKDTree(0.5 * (p0 + p1)).sparse_distance_matrix(
            tree, (distance + 0.5 * h + half) * (1 + ROUND_OFF), output_type="ndarray")
        cell = found["i"] if cells is None else cells[found["i"]]
        key = np.unique(cell.astype(np.int64) * len(self.index) + piece_of[found["j"]])
        return key // len(self.index), key % len(self.index)

    def pieces(self):
        """(cKDTree of the pieces' centres, each piece's obstacle segment, the largest
        half-length): the obstacle segments cut into pieces no longer than the longest
        cell of the reference configuration (built once: the obstacles are fixed)."""
        if self._pieces is None:
            from scipy.spatial import cKDTree
            length = np.linalg.norm(self.q1 - self.q0, axis=1)
            count = np.maximum(1, np.ceil(length / self.line.lengths.max())).astype(np.int64)
            piece_of = np.repeat(np.arange(len(count)), count)
            first = np.cumsum(count) - count
            share = (np.arange(count.sum()) - first[piece_of] + 0.5) / count[piece_of]
            q0, q1 = self.q0[piece_of], self.q1[piece_of]
            centres = q0 + share[:, None] * (q1 - q0)
            self._pieces = (cKDTree(centres), piece_of,
                            float(np.max(0.5 * length / count)))
        return self._pieces

    def evaluate(self, owned_displacement: np.ndarray) -> PairTerms:
        """The (segment, obstacle) pairs within the barrier's reach at this state and
        their energies, gradients (m, 3k) and Hessians (m, 3k, 3k) in the rod's nodes of
        each pair (k = 2: the segment's; 4: its curve's stencil) (collective; kept for
        the Jacobian at the same state)."""
        P = self.line.positions(owned_displacement)
        key, value = self._cache
        if key is not None and np.array_equal(key, P):
            return value
        with np.errstate(invalid="ignore", divide="ignore"):  # an iterate through the
            if self.stencils is None:                          # axis (d = 0): NaN, Newton
                cell, j, s, t, d = self.near(P, self.law.gap)  # fails, the step is cut
                nodes = self.line.ends[cell]
                X = np.concatenate([P[nodes], np.stack([self.q0[j], self.q1[j]], axis=1)],
                                   axis=1)
                E, G, H = pair_energy(X, 0.5 * self.contact_radius[j], self.law.gap,
                                      self.law.stiffness, self.weight[cell],
                                      closest=(s, t, d))
            else:
                cell, j, (s, t, d, free_) = self.curve_contacts(P, self.law.gap)
                nodes = self.stencils.nodes[cell]
                E, G, H = smooth_pair_energy(
                    self.curve_nodes(P, cell, j), *self.curve_weights(cell), s, t, free_,
                    0.5 * self.contact_radius[j], self.law.gap, self.law.stiffness,
                    self.weight[cell])
        k = 3 * nodes.shape[1]
        value = PairTerms(np.column_stack([cell, self.index[j]]), nodes, E, G[:, :k],
                          H[:, :k, :k])
        self._cache = (P, value)
        return value

    # -- the rod's C^1 curves (contact.obstacle_curve = "smooth") -----------------------

    def curve_nodes(self, P: np.ndarray, cell: np.ndarray, j: np.ndarray) -> np.ndarray:
        """(m, 8, 3) the stencil nodes of the cells' curves and of the obstacles'
        segments j (q0, q0, q1, q1: ``curve_weights`` makes it the straight segment)."""
        Q = np.stack([self.q0[j], self.q0[j], self.q1[j], self.q1[j]], axis=1)
        return np.concatenate([P[self.stencils.nodes[cell]], Q], axis=1)

    def curve_weights(self, cell: np.ndarray):
        """(wa, wb) as smooth_pairs.closest takes them: the cells' Catmull-Rom weights
        and the obstacle segment's linear ones (w = (0, 1 - u, u, 0))."""
        def straight(rows, u):
            u = np.asarray(u, float)
            zero, one = np.zeros_like(u), np.ones_like(u)
            return (np.column_stack([zero, 1 - u, u, zero]),
                    np.column_stack([zero, -one, one, zero]), np.zeros((len(u), 4)))
        return (lambda rows, u: self.stencils.weights(cell[rows], u)), straight

    def curve_contacts(self, P: np.ndarray, within: float):
        """(cells, obstacle segments j, (s, t, d, free)) of the close approaches of the
        rod's curves to the obstacles nearer than contact radius + ``within``, each
        counted once: a curve lies within its deviation of its chord, so the chords
        nearer than that bound are the candidates; their curves' closest points
        (smooth_pairs.closest, from the chords'), kept where the minimiser belongs to the
        cell (smooth_pairs.counted: not to its neighbour along the rod); the obstacle's
        parameter free inside its segment of length > 0 (a sphere's centre: held)."""
        cell, j, s, t, d = self.near_chords(P, within)
        s, t, d, sigma, _ = closest(self.curve_nodes(P, cell, j), *self.curve_weights(cell),
                                    s, t)
        st = self.stencils
        before, after = st.prev[cell] >= 0, st.next[cell] >= 0
        keep = (d < self.contact_radius[j] + within) & counted(sigma, before, after)
        length = np.linalg.norm(self.q1 - self.q0, axis=1)[j]
        free_ = np.array([free(s, before, after), (t > 0) & (t < 1) & (length > 0)])
        return cell[keep], j[keep], (s[keep], t[keep], d[keep], free_[:, keep])

    def near_chords(self, P: np.ndarray, within: float):
        """(cell, j, s, t, d) of the chords (``near``) whose curves may be nearer than
        contact radius + ``within``: the chords nearer than that plus the curve's
        deviation from its chord (smooth_pairs.Stencils)."""
        deviation = self.stencils.deviation(P)
        cell, j, s, t, d = self.near(P, within + deviation.max(initial=0.0))
        keep = d - deviation[cell] < self.contact_radius[j] + within
        return cell[keep], j[keep], s[keep], t[keep], d[keep]

    def pair_nodes(self, cells: np.ndarray) -> np.ndarray:
        """(m, 4) the stencil nodes of the cells' curves (BoundTerm's pattern entries)."""
        return self.stencils.nodes[cells]

    def forget(self) -> None:
        """The next :meth:`evaluate` computes the terms anew even at the same state (the
        cost of a new state, benchmarks/obstacle_segments.py)."""
        self._cache = (None, None)

    def forget_candidates(self) -> None:
        """The next :meth:`near` searches its candidates anew (the broad phase's cost,
        benchmarks/obstacle_broad_phase.py)."""
        self._candidates = (None, 0.0, None)

    def for_step(self, stages, fields, previous, before_previous) -> StepTerm:
        """The term in a per-step scheme's residual (pair_contact.StepTerm)."""
        block = next(k for k, y in enumerate(fields) if y is self.x)
        return StepTerm(self, stages, previous[block], before_previous[block])

    def bind(self, system, step: StepTerm | None = None) -> "BoundSegments":
        return BoundSegments(self, system, step)

    # -- gaps, checks, diagnostics ------------------------------------------------------

    def closest(self) -> tuple[float, float, int]:
        """(smallest gap, s of its segment's midpoint, obstacle index k) of the current
        state (the same on every rank: the gathered centre line); of the rod's curves
        with contact.obstacle_curve = "smooth" (searched among the chords whose gap less
        their curve's deviation is at most the least chord gap plus deviation)."""
        P = self.line.positions(self.owned_displacement())
        g, cell, j = self.smallest(P)
        if self.stencils is None:
            return g, float(self.line.mid_s[cell]), int(self.index[j])
        deviation = self.stencils.deviation(P)
        margin = 2 * deviation.max() + ROUND_OFF * (abs(g) + self.contact_radius.max())
        cell, j, s, t, d = self.near(P, g + margin)
        gaps = d - self.contact_radius[j]
        keep = gaps - deviation[cell] <= np.min(gaps + deviation[cell])
        cell, j = cell[keep], j[keep]
        d = closest(self.curve_nodes(P, cell, j), *self.curve_weights(cell), s[keep],
                    t[keep])[2]
        gaps = d - self.contact_radius[j]
        k = int(np.argmin(gaps))
        return float(gaps[k]), float(self.line.mid_s[cell[k]]), int(self.index[j[k]])

    def smallest(self, P: np.ndarray) -> tuple[float, int, int]:
        """(smallest gap, its cell, its obstacle segment j) at positions P (the first in
        the order (cell, then j) where several are equal)."""
        if self.tree:
            cell, j = self.nearest(P)
            gaps = self.pair_distances(P, cell, j)[2] - self.contact_radius[j]
        else:
            _, _, d = self.distances(P)
            cell, j = (v.ravel() for v in np.indices(d.shape))
            gaps = (d - self.contact_radius).ravel()
        k = np.argmin(gaps)
        return float(gaps[k]), int(cell[k]), int(j[k])

    def nearest(self, P: np.ndarray):
        """(cell, j) in the order (cell, then j), a superset of the pairs whose gap is the
        smallest at P: U, the smallest gap of each cell to the obstacle segment of its
        nearest piece, bounds it; the cells whose midpoint is nearer than U + R + r +
        h / 2 + l / 2 to some piece (R + r the largest contact radius) are searched
        within U + R + r."""
        tree, piece_of, half = self.pieces()
        ends = self.line.ends
        p0, p1 = P[ends[:, 0]], P[ends[:, 1]]
        h = np.sqrt(np.max(np.einsum("ij,ij->i", p1 - p0, p1 - p0), initial=0.0))
        apart, piece = tree.query(0.5 * (p0 + p1))
        j = piece_of[piece]
        cells = np.arange(len(ends))
        bound = float(np.min(self.pair_distances(P, cells, j)[2] - self.contact_radius[j]))
        distance = (bound + float(self.contact_radius.max())) * (1 + ROUND_OFF)
        return self.search(P, distance, cells[apart <= (distance + 0.5 * h + half)
                                              * (1 + ROUND_OFF)])

    def commit(self) -> None:
        """After an accepted step (and at the start): friction's power of the force the
        step applied (its frozen segments, the step's velocities), then the segments
        frozen anew at this state."""
        if self.friction is None:
            return
        u = self.owned_displacement()
        friction, V = self.friction, self.velocities(u)
        friction.dissipation, friction.force = friction.power(V)
        friction.total = friction.total_force(V)
        friction.lag(self.line.positions(u))

    def check_state(self) -> str | None:
        """A reason to reject a converged step (or the initial state): a segment at or
        inside an obstacle's radius plus r."""
        g, s, k = self.closest()
        if g > 0:
            return None
        return (f"the centre line's segment at s = {s:.4g} is {-g:.3g} inside obstacles[{k}] "
                f"(gap {g:.3g}; the barrier was overcome: raise contact.stiffness)")

    def diagnostics(self) -> dict[str, float]:
        """The segments' barrier energy, their total contact force on the rod (x, y, z)
        and the smallest gap, of the current state."""
        terms = self.evaluate(self.owned_displacement())
        force = -terms.gradient.reshape(-1, 3).sum(axis=0)
        out = {"contact_energy": float(terms.energy.sum()), "min_gap": self.closest()[0]}
        out.update({f"contact_force_{c}": float(force[i]) for i, c in enumerate("xyz")})
        if self.friction is not None:       # of the force the last step applied (commit)
            out["friction_dissipation"] = self.friction.dissipation
            out.update({f"contact_force_{c}": out[f"contact_force_{c}"]
                        + float(self.friction.total[i]) for i, c in enumerate("xyz")})
        return out

    def force_density(self) -> np.ndarray:
        """(owned nodes, 3) the segments' contact force per unit length at the nodes."""
        return nodal_force_density(self.line, self.evaluate(self.owned_displacement()))


class ObstacleFriction(PairFriction):
    """Coulomb friction of the segments on the obstacles of ``contact`` (an
    ObstacleSegments; mu per obstacle segment): pair_friction's law and its residual and
    Jacobian per unit rate, with the obstacle at rest (module docstring).
    ``directional``: (forward, backward, lateral) per obstacle segment, or None (all
    isotropic): the obstacles' directional friction (contact.py's law on the nodes): the
    slip u split along the rod's axis at the contact point projected on the tangent
    plane, a (towards s = L: forward), and across it, b = n x a, frozen with the
    contact; F = -lambda m (mu_a(u_a) u_a a + mu_l u_b b), mu_a blended from backward to
    forward by u_a / sqrt(u_a^2 + eps^2)."""

    def __init__(self, contact: ObstacleSegments, mu: np.ndarray,
                 directional: np.ndarray | None = None):
        super().__init__(contact.line, contact.law, 0.0, 0.0)
        self.contact, self.mu_of, self.directional = contact, mu, directional
        self.coefficients = self.axis = self.across = None     # per frozen contact
        self.nodes, self.w = np.zeros((0, 2), dtype=np.int64), np.zeros((0, 2))
        self.total = np.zeros(3)        # the force the last step applied (commit)

    def total_force(self, V: np.ndarray) -> np.ndarray:
        """The frozen segments' friction forces on the rod, summed, at the nodes'
        velocities V."""
        u, _, m = self.slip(V)
        return -((self.bound * m)[:, None] * self.resisted(u)[0]).sum(axis=0)

    def lag(self, P: np.ndarray) -> None:
        """Freeze the segments (or curves) within the barrier's reach of positions P
        (nodes, 3): closest points, normals, normal forces; those without friction
        dropped."""
        c, law = self.contact, self.law
        if c.stencils is None:
            cell, j, s, t, d = c.near(P, law.gap)
            nodes, w = self.line.ends[cell], np.stack([1 - s, s], axis=1)
            slope = np.tile([-1.0, 1.0], (len(cell), 1))        # the segment's d/ds
            wq = np.stack([1 - t, t], axis=1)
            Q = np.stack([c.q0[j], c.q1[j]], axis=1)
        else:
            cell, j, (s, t, d, _) = c.curve_contacts(P, law.gap)
            nodes = c.stencils.nodes[cell]
            w, slope = c.stencils.weights(cell, s)[:2]
            wq = c.curve_weights(cell)[1](None, t)[0]
            Q = c.curve_nodes(P, cell, j)[:, 4:]
        rubbing = self.mu_of[j] > 0
        cell, j, d, nodes, w, slope = (cell[rubbing], j[rubbing], d[rubbing], nodes[rubbing],
                                       w[rubbing], slope[rubbing])
        lam = -law.stiffness * c.weight[cell] * barrier_derivatives(
            d - c.contact_radius[j], law.gap)[1]
        n = (np.einsum("mk,mki->mi", w, P[nodes])
             - np.einsum("mk,mki->mi", wq[rubbing], Q[rubbing])) / d[:, None]
        self.pairs = np.column_stack([cell, c.index[j]])
        self.nodes, self.w = nodes, w
        self.T = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
        self.bound = self.mu_of[j] * lam
        if self.directional is not None:      # the rod's axis on the tangent plane
            axis = np.einsum("mij,mj->mi", self.T,
                             np.einsum("mk,mki->mi", slope, P[nodes]))
            self.axis = axis / np.maximum(np.linalg.norm(axis, axis=1), 1e-300)[:, None]
            self.across = np.cross(n, self.axis)
            self.coefficients, self.bound = self.directional[j], lam

    def resisted(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """PairFriction.resisted: isotropic, or the directional law's weighted slip
        mu_a(u_a) u_a a + mu_l u_b b and its derivative (class docstring)."""
        if self.coefficients is None:
            return super().resisted(u)
        a, b = self.axis, self.across
        forward, backward, lateral = self.coefficients.T
        u_a, u_b = np.einsum("mi,mi->m", u, a), np.einsum("mi,mi->m", u, b)
        eps2 = self.law.slip_tolerance ** 2
        root = np.sqrt(u_a**2 + eps2)
        mu_a = 0.5 * (forward + backward) + 0.5 * (forward - backward) * u_a / root
        slope = mu_a + 0.5 * (forward - backward) * eps2 * u_a / root**3   # d(mu_a u_a)/du_a
        aa, bb = a[:, :, None] * a[:, None, :], b[:, :, None] * b[:, None, :]
        return ((mu_a * u_a)[:, None] * a + (lateral * u_b)[:, None] * b,
                slope[:, None, None] * aa + lateral[:, None, None] * bb)


class BoundSegments(BoundTerm):
    """ObstacleSegments in one assembled system: pair_contact.BoundTerm's residual rows
    and Jacobian entries of the owned nodes; no entries beyond the rod's own (a cell's
    two nodes) and no limit on Newton's updates (as the nodal law: the barrier's Taylor
    range holds the iterates, the accepted states are checked)."""

    def missing_entries(self):
        """None on the segments (a cell's two nodes: the rod's own entries); on the
        curves (k = 4 stencil nodes) the entries of the cells at the last residual's
        states and of the friction's frozen cells that the matrix lacks, with those of
        the cells within one more barrier gap (the cells that may come next), as
        BoundTerm.missing_entries."""
        contact = self.contact
        if contact.stencils is None or not self.solved or self._state is None:
            return None
        cells = np.concatenate([contact.evaluate(state).pairs[:, 0]
                                for _, _, state in self._state]
                               + ([contact.friction.pairs[:, 0]]
                                  if contact.friction is not None else []))
        if np.isin(cells, self.in_pattern).all():
            return None
        coming = []
        for _, _, state in self._state:
            coming.append(contact.near_chords(contact.line.positions(state),
                                              2 * contact.law.gap)[0])
        cells = np.union1d(cells, np.concatenate(coming))
        self.in_pattern = np.union1d(self.in_pattern, cells)
        return self._entries(cells)

    def step_factor(self, x_owned: np.ndarray, y_owned: np.ndarray) -> float:
        return 1.0
