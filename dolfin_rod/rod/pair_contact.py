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

Coulomb friction of the pairs (``contact.self_friction``, ``between_rods_friction``):
pair_friction.py, with the pairs and normal forces lagged at each accepted state
(``commit``) and the nodes' velocities of the step's affine rate map (``set_rates``).
"""

from __future__ import annotations

import math

import numpy as np
from petsc4py import PETSc

from .contact import barrier_derivatives
from .pair_friction import PairFriction
from .segments import closest_points, near_pairs

CROSSING_DEPTH = 24     # bisections of a step's path before a pair counts as crossed
STEP_FLOOR = 0.1        # a Newton update keeps every pair's gap above this share of its gap


def exclusion(radius: float, gap: float, h: float) -> float:
    """The distance in s within which segments of one rod are neighbours, not a pair."""
    return math.pi * (radius + gap) + h


def distance_derivatives(X):
    """Centre-line distance d of segment pairs X (m, 4, 3) = (p0, p1, q0, q1) and its
    gradient (m, 12) and Hessian (m, 12, 12) with respect to the 12 coordinates."""
    p0, p1, q0, q1 = (X[:, k] for k in range(4))
    s, t, d = closest_points(p0, p1, q0, q1)
    d1, d2 = p1 - p0, q1 - q0
    D = p0 + s[:, None] * d1 - q0 - t[:, None] * d2
    w = np.stack([1 - s, s, -(1 - t), -t], axis=1)                  # D = sum_k w_k X_k
    eye = np.eye(3)
    f_X = 2 * (w[:, :, None] * D[:, None, :]).reshape(-1, 12)        # grad of d^2
    f_XX = 2 * np.einsum("mk,ml,ij->mkilj", w, w, eye).reshape(-1, 12, 12)
    ds_w, dt_w = np.array([-1.0, 1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0, -1.0])
    f_Xs = 2 * (ds_w[None, :, None] * D[:, None, :] + w[:, :, None] * d1[:, None, :])
    f_Xt = 2 * (dt_w[None, :, None] * D[:, None, :] - w[:, :, None] * d2[:, None, :])
    free = np.stack([(s > 0) & (s < 1), (t > 0) & (t < 1)], axis=1)
    B = np.stack([f_Xs.reshape(-1, 12), f_Xt.reshape(-1, 12)], axis=2) * free[:, None, :]
    a, b, e = (np.einsum("ij,ij->i", u, v) for u, v in ((d1, d1), (d1, d2), (d2, d2)))
    K = 2 * np.stack([np.stack([a, -b], 1), np.stack([-b, e], 1)], 1)
    both = free[:, 0] & free[:, 1]
    K[~both, 0, 1] = K[~both, 1, 0] = 0.0
    K[~free[:, 0], 0, 0] = K[~free[:, 1], 1, 1] = 1.0
    H2 = f_XX - B @ np.linalg.solve(K, np.transpose(B, (0, 2, 1)))
    grad = f_X / (2 * d[:, None])
    hess = (H2 - 2 * grad[:, :, None] * grad[:, None, :]) / (2 * d[:, None, None])
    return d, grad, hess


def pair_energy(X, radius: float, gap: float, stiffness, weights, order: int = 2):
    """Energy (m,), gradient (m, 12) and (order 2) Hessian (m, 12, 12) of segment pairs
    X (m, 4, 3) with weights w_ij (m,): E = kappa w b(d - 2 r)."""
    d, grad, hess = distance_derivatives(X)
    b, b1, b2 = barrier_derivatives(d - 2 * radius, gap)
    k = stiffness * np.asarray(weights, float)
    E, G = k * b, (k * b1)[:, None] * grad
    if order < 2:
        return E, G, None
    H = (k * b2)[:, None, None] * grad[:, :, None] * grad[:, None, :] + \
        (k * b1)[:, None, None] * hess
    return E, G, H


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


class SegmentContact:
    """Self-contact (pairs within a rod) and contact between rods (``between_rods``) of
    the segments of ``x`` (the rod's displacement, P1), a term that fem/assembly adds to
    the residual and Jacobian of the systems that hold x (``bind``); law: the contact
    law (radius, gap, stiffness; friction coefficients and slip tolerance: with
    ``velocity``, x's rate, the pairs' Coulomb friction, pair_friction.py); joints: the
    nodes (s_a, s_b) of the rods' joints."""

    def __init__(self, x, law, rod_of, self_contact: bool, between_rods: bool,
                 joints=(), velocity=None):
        self.x, self.law = x, law
        self.line = Centreline(x, rod_of)
        mu = (law.self_friction * self_contact, law.between_rods_friction * between_rods)
        self.friction = (PairFriction(self.line, law, *mu)
                         if velocity is not None and max(mu) > 0 else None)
        self.velocity_field, self.rates = velocity, None
        h = float(np.max(self.line.lengths))
        self.exclusion = exclusion(law.radius, law.gap, h)
        self.through_joints = self._joint_distances(joints)
        self.self_contact, self.between_rods = self_contact, between_rods
        self.reach = 2 * law.radius + law.gap       # pairs act below this distance
        self._cache = (None, None)
        self.start = None                            # positions at the last commit
        self.block = 0          # the displacement's block in the problem (model sets it)
        self.rod_names, self.rod_starts = ("rod",), (0.0,)  # the rods' (model sets them)

    # -- pairs and their terms ----------------------------------------------------------

    def pairs(self, P: np.ndarray, distance: float | None = None) -> np.ndarray:
        """(m, 2) segment pairs of positions P whose centre lines are nearer than
        ``distance`` (default the barrier's reach), filtered by self/between rods."""
        line = self.line
        p0, p1 = P[line.ends[:, 0]], P[line.ends[:, 1]]
        # the exclusion in s applies within a rod: other rods are placed a rod's length
        # or more apart in s (layout.py), so the s test never removes them
        pairs = near_pairs(p0, p1, line.mid_s, self.reach if distance is None else distance,
                           self.exclusion)
        same = line.rod[pairs[:, 0]] == line.rod[pairs[:, 1]]
        keep = (same & self.self_contact) | (~same & self.between_rods)
        for near in self.through_joints:        # neighbours through a joint
            keep &= near[pairs[:, 0]] + near[pairs[:, 1]] >= self.exclusion
        return pairs[keep]

    def _joint_distances(self, joints) -> list[np.ndarray]:
        """Per joint point (the nodes (s_a, s_b) of the joints, those sharing a node
        merged: one place in space) each segment's distance in s to the nearest of its
        nodes: two segments whose distances add up to less than the exclusion are
        neighbours through the joint (as within a rod), no pair."""
        groups: list[set] = []
        for joint in joints:
            linked = [g for g in groups if g & set(joint)]
            merged = set(joint).union(*linked)
            groups = [g for g in groups if g not in linked] + [merged]
        return [np.min(np.abs(self.line.mid_s[:, None] - np.array(sorted(g))[None, :]),
                       axis=1) for g in groups]

    def _coordinates(self, P, pairs):
        e = self.line.ends
        return np.concatenate([P[e[pairs[:, 0]]], P[e[pairs[:, 1]]]], axis=1)

    def evaluate(self, owned_displacement: np.ndarray):
        """(global nodes (m, 4), E, G, H) of the active pairs at this state (collective;
        kept for the Jacobian at the same state)."""
        P = self.line.positions(owned_displacement)
        key, value = self._cache
        if key is not None and np.array_equal(key, P):
            return value
        pairs = self.pairs(P)
        nodes = np.concatenate([self.line.ends[pairs[:, 0]], self.line.ends[pairs[:, 1]]], 1)
        weights = 0.5 * (self.line.lengths[pairs[:, 0]] + self.line.lengths[pairs[:, 1]])
        E, G, H = pair_energy(self._coordinates(P, pairs), self.law.radius, self.law.gap,
                              self.law.stiffness, weights)
        value = (nodes, E, G, H)
        self._cache = (P, value)
        return value

    def forget(self) -> None:
        """The next :meth:`evaluate` finds the pairs anew even at the same state (the
        cost of a new state, benchmarks/contact_assembly.py)."""
        self._cache = (None, None)

    def owned_displacement(self) -> np.ndarray:
        return self.x.x.array[: 3 * self.line.n_owned]

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

    def for_step(self, stages, fields, previous, before_previous) -> "StepTerm":
        """The term in a per-step scheme's residual sum_k w_k F(Y_k, ...) (stages: (w_k,
        (a0, a1, a2)) with Y_k = a0 y + a1 y_n + a2 y_{n-1}; fields, previous,
        before_previous: the problem's unknowns y and their y_n, y_{n-1})."""
        block = next(k for k, y in enumerate(fields) if y is self.x)
        return StepTerm(self, stages, previous[block], before_previous[block])

    def bind(self, system) -> "BoundTerm":
        """The term in an assembled ``system`` (fem/assembly) one of whose unknowns is x
        (any block: the tangent stiffness of analysis/ holds the mechanical blocks only),
        or whose block ``self.block`` (the model's displacement block) holds another
        unknown of its space (the start's accelerations: then x is fixed and the term
        adds its residual only)."""
        return BoundTerm(self, system)

    # -- diagnostics ------------------------------------------------------------------

    def diagnostics(self) -> dict[str, float]:
        """Pair energy, the sum of the pair forces' magnitudes, the smallest pair gap
        (capped at the barrier's gap delta: farther pairs are not searched) and the
        count of pairs within the barrier's reach, of the current state."""
        nodes, E, G, _ = self.evaluate(self.owned_displacement())
        P = self.line.positions(self.owned_displacement())
        gaps = self._gaps(P, self.pairs(P))
        out = {"pair_contact_energy": float(E.sum()),
               "pair_contact_force": float(np.linalg.norm(G[:, :6].reshape(-1, 2, 3).sum(1),
                                                          axis=1).sum()),
               "min_pair_gap": float(gaps.min(initial=self.law.gap)),
               "contact_pairs": float(len(E))}
        if self.friction is not None:       # of the force the last step applied (commit)
            out["pair_friction_dissipation"] = self.friction.dissipation
            out["pair_friction_force"] = self.friction.force
        return out

    def _gaps(self, P, pairs):
        X = self._coordinates(P, pairs)
        return closest_points(X[:, 0], X[:, 1], X[:, 2], X[:, 3])[2] - 2 * self.law.radius

    def force_density(self) -> np.ndarray:
        """(owned nodes, 3) the pairs' contact force per unit length at the owned nodes
        (the nodes' forces over their share of the reference length, h/2 per cell)."""
        nodes, _, G, _ = self.evaluate(self.owned_displacement())
        forces = np.zeros((self.line.n_nodes, 3))
        np.add.at(forces, nodes.ravel(), -G.reshape(-1, 3))
        share = np.zeros(self.line.n_nodes)
        np.add.at(share, self.line.ends.ravel(), np.repeat(self.line.lengths / 2, 2))
        owned = self.line.owned_global
        return forces[owned] / share[owned, None]

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

    def _where(self, pair, what: str, P: np.ndarray | None = None) -> str:
        """The pair's segments named by rod and arc length (their midpoints), the point
        between their closest points at positions P (default the current state), and
        ``what``."""
        P = self.line.positions(self.owned_displacement()) if P is None else P
        X = self._coordinates(P, np.asarray(pair)[None])[0]
        s, t, _ = closest_points(*(X[k][None] for k in range(4)))
        point = 0.5 * (X[0] + s[0] * (X[1] - X[0]) + X[2] + t[0] * (X[3] - X[2]))
        names = [self.segment_name(k) for k in pair]
        return (f"segments of {names[0]} and {names[1]}, near ("
                f"{', '.join(f'{v:.4g}' for v in point)}): {what}")

    def segment_name(self, k: int) -> str:
        """'rod NAME at s = ...' of segment k (its midpoint's arc length on its rod)."""
        rod = int(self.line.rod[k])
        start, name = self.rod_starts[rod], self.rod_names[rod]
        return f"{'the rod' if len(self.rod_names) == 1 else f'rod {name}'} at s = " \
               f"{self.line.mid_s[k] - start:.4g}"

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
        pairs = self.pairs(P0, 2 * move.max() + self.reach)
        if not len(pairs):
            return None
        e = self.line.ends
        L = move[e[pairs[:, 0]]].max(1) + move[e[pairs[:, 1]]].max(1)

        def dist(tau, k):
            nodes = e[pairs[k]].reshape(len(k), 4)
            P = P0[nodes] + tau[:, None, None] * (P1 - P0)[nodes]
            return closest_points(P[:, 0], P[:, 1], P[:, 2], P[:, 3])[2]

        idx = np.arange(len(pairs))
        a, b = np.zeros(len(pairs)), np.ones(len(pairs))
        da, db = dist(a, idx), dist(b, idx)
        low = floor(da)
        for _ in range(CROSSING_DEPTH):
            near = np.minimum(da, db) <= low[idx]
            if near.any():
                return pairs[idx[near][0]]
            open_ = da + db - L[idx] * (b - a) <= 2 * low[idx]
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
        towards P1 up to it no pair's gap falls below STEP_FLOOR of its gap at P0 (a pair
        already closer than 2 r: below half its distance)."""
        r2 = 2 * self.law.radius

        def floor(d0):
            return np.where(d0 > r2, r2 + STEP_FLOOR * (d0 - r2), 0.5 * d0)

        alpha = 1.0
        for _ in range(CROSSING_DEPTH):
            if self.first_too_near(P0, P0 + alpha * (P1 - P0), floor) is None:
                return alpha
            alpha *= 0.5
        return alpha


class StepTerm:
    """SegmentContact in a per-step scheme's residual (SegmentContact.for_step): stage k
    adds w_k dE/dX(Y_k) to the residual and w_k a0_k H(Y_k) to the Jacobian, Y_k the
    stage's displacement (a0 x + a1 x_n + a2 x_{n-1})."""

    def __init__(self, contact: SegmentContact, stages, previous, before_previous):
        self.contact, self.stages = contact, list(stages)
        self.previous, self.before_previous = previous, before_previous

    def bind(self, system) -> "BoundTerm":
        return BoundTerm(self.contact, system, self)

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
        self._state = None
        self._friction = None       # the friction's (nodes, G, dR/dV) at _state

    def add_residual(self, x_owned: np.ndarray, b_owned: np.ndarray) -> None:
        """b += dE/dX at the owned nodes' rows (x: the system's owned unknowns), and the
        friction's -w_k F (pair_friction.py; generalized-alpha's steps only)."""
        contact = self.contact
        u = x_owned[self.local_rows] if self.solved else contact.owned_displacement()
        self._state = [(1.0, 1.0, u)] if self.step is None else self.step.states(u)
        for weight, _, state in self._state:
            nodes, _, G, _ = contact.evaluate(state)
            self._add_rows(b_owned, nodes, weight * G)
        if contact.friction is not None:
            self._friction = contact.friction.residual(contact.velocities(u))
            self._add_rows(b_owned, *self._friction[:2])

    def _add_rows(self, b_owned: np.ndarray, nodes: np.ndarray, G: np.ndarray) -> None:
        mine = self.owned[nodes.ravel()]
        rows = self.local_rows.reshape(-1, 3)[self.row_of_node[nodes.ravel()[mine]]]
        np.add.at(b_owned, rows.ravel(), G.reshape(-1, 3)[mine].ravel())

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

    def add_jacobian(self, A) -> None:
        """A += the pairs' Hessians (rows of owned nodes) at the last residual's state,
        and the friction's dR/dV times the rates' slope dV/dx; new entries grow A's
        sparsity."""
        if not self.solved or self._state is None:
            return
        for weight, a0, state in self._state:
            nodes, _, _, H = self.contact.evaluate(state)
            if weight * a0 != 0.0:
                self._add_matrix(A, nodes, weight * a0 * H)
        rates = self.contact.rates
        if self.contact.friction is not None and rates is not None:
            nodes, _, H = self._friction
            self._add_matrix(A, nodes, rates[0] * H)

    def _add_matrix(self, A, nodes: np.ndarray, H: np.ndarray) -> None:
        """A += the 12 x 12 blocks H of the pairs' nodes (rows of owned nodes)."""
        if not len(nodes):
            return
        rows = self.global_rows[nodes].reshape(-1, 12)
        owned = np.repeat(self.owned[nodes], 3, axis=1)
        # one call for all pairs (PETSc's loop); rows of other ranks' nodes as -1: skipped
        A.setValuesRCV(np.where(owned, rows, -1).astype(PETSc.IntType),
                       rows.astype(PETSc.IntType), H, addv=PETSc.InsertMode.ADD_VALUES)
