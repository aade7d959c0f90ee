"""Coulomb friction between segments in contact (self-contact and contact between rods;
issue 26, docs/contact.md): the law of the obstacles' friction (contact.py) at the
closest points of a segment pair, with the pair's lagged normal force.

At every accepted state (``lag``) each pair within the barrier's reach is frozen: its
closest-point parameters (s, t), unit normal n (from q(t) to p(s)), the tangent
projector T = I - n n^T and its normal force lambda = -kappa w b'(g) >= 0 (the force
of the pair's energy, pair_contact.py).  In the next step the pair carries the friction
force on its first segment

    F = -mu lambda phi(|u| / eps) u / |u|,   u = T (v_p(s) - v_q(t)),

phi the obstacles' smoothed sticking law (contact.mollifier: 3y/2 - y^3/2 below 1, 1
beyond), eps the slip tolerance, v_p(s) = (1 - s) V_p0 + s V_p1 the velocity of the
closest point of segment p (q's likewise), and -F on the second segment; node k of the
pair gets w_k F, w = (1 - s, s, -(1 - t), -t).  A pair held by static friction
(tangential load below mu lambda) slides slower than eps; beyond eps the force is
Coulomb's mu lambda.  The force acts at the centre lines (no couple r n x F on the
sections: rolling is not modelled).  Its power -F.(v_p - v_q) = mu lambda phi |u| >= 0
is the friction's dissipation rate.

The residual gets -w_k F at the pair's nodes, the Jacobian dR/dV times the rate's slope
dV/dx of the time step (the integrator's affine map of the rates, SegmentContact.rates):
dR_k/dV_l = w_k w_l mu lambda (m / eps T + 2 m' / eps^3 u u^T) T with m(y^2) = phi(y)/y,
a positive semidefinite 3x3 block per node pair (not symmetric across the pair's
velocity and position columns: friction is no energy).
"""

from __future__ import annotations

import numpy as np

from .contact import NP_OPS, barrier_derivatives, mollifier
from .segments import closest_points


def mollifier_slope(y2):
    """d m / d(y^2) of contact.mollifier (numpy): -1/2 below 1, -y^-3 / 2 beyond."""
    return np.where(y2 < 1.0, -0.5, -0.5 * np.maximum(y2, 1.0) ** -1.5)


class PairFriction:
    """The friction of the segment pairs of ``line`` (pair_contact.Centreline) under the
    contact ``law`` (radius, gap, stiffness, slip tolerance); ``mu_self`` for pairs
    within a rod, ``mu_between`` for pairs of different rods (``owner``: each segment's
    rod, pair_contact.SegmentContact.owner; default the line's)."""

    def __init__(self, line, law, mu_self: float, mu_between: float, owner=None):
        self.line, self.law = line, law
        self.owner = line.rod if owner is None else owner
        self.mu = (mu_self, mu_between)
        self.pairs = np.zeros((0, 2), dtype=np.int64)     # the frozen pairs' segments
        self.nodes = np.zeros((0, 4), dtype=np.int64)
        self.w = np.zeros((0, 4))
        self.T = np.zeros((0, 3, 3))
        self.bound = np.zeros(0)           # mu lambda per frozen pair
        self.dissipation = 0.0             # of the force the last step applied (commit)
        self.force = 0.0                   # the sum of its magnitudes

    def lag(self, P: np.ndarray, pairs: np.ndarray) -> None:
        """Freeze the pairs (m, 2) of positions P (nodes, 3): closest points, normals,
        normal forces (module docstring); pairs without normal force are dropped."""
        e, law = self.line.ends, self.law
        X = np.concatenate([P[e[pairs[:, 0]]], P[e[pairs[:, 1]]]], axis=1)
        s, t, d = closest_points(X[:, 0], X[:, 1], X[:, 2], X[:, 3])
        weights = 0.5 * (self.line.lengths[pairs[:, 0]] + self.line.lengths[pairs[:, 1]])
        lam = -law.stiffness * weights * barrier_derivatives(d - 2 * law.radius, law.gap)[1]
        same = self.owner[pairs[:, 0]] == self.owner[pairs[:, 1]]
        bound = np.where(same, self.mu[0], self.mu[1]) * lam
        keep = bound > 0
        s, t, X = s[keep], t[keep], X[keep]
        n = (X[:, 0] + s[:, None] * (X[:, 1] - X[:, 0])
             - X[:, 2] - t[:, None] * (X[:, 3] - X[:, 2]))
        n /= np.linalg.norm(n, axis=1)[:, None]
        self.pairs = pairs[keep]
        self.nodes = np.concatenate([e[pairs[keep, 0]], e[pairs[keep, 1]]], axis=1)
        self.w = np.stack([1 - s, s, -(1 - t), -t], axis=1)
        self.T = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
        self.bound = bound[keep]

    def slip(self, V: np.ndarray):
        """The tangential relative velocities u (m, 3) of the frozen pairs and
        m(|u|^2 / eps^2) / eps (m,) at the nodes' velocities V (nodes, 3)."""
        rel = np.einsum("mk,mki->mi", self.w, V[self.nodes])
        u = np.einsum("mij,mj->mi", self.T, rel)
        eps = self.law.slip_tolerance
        y2 = np.einsum("mi,mi->m", u, u) / eps**2
        return u, y2, mollifier(y2, NP_OPS) / eps

    def resisted(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the slip that the friction resists, r(u) (m, 3), and dr/du on the tangent
        plane (m, 3, 3)): the slip u itself, T (isotropic: F = -mu lambda m u); a
        directional law weighs its parts (obstacle_segments.ObstacleFriction)."""
        return u, self.T

    def residual(self, V: np.ndarray):
        """(pair nodes (m, 4), residual entries (m, 12) = -w_k F, Jacobian per unit rate
        (m, 12, 12) dR/dV) at the nodes' velocities V (nodes, 3); (m, 2), (m, 6),
        (m, 6, 6) for segments on obstacles (obstacle_segments.ObstacleFriction).
        F = -bound m(|u|^2 / eps^2) r(u) (``resisted``)."""
        u, y2, m = self.slip(V)
        r, dr = self.resisted(u)
        F = -(self.bound * m)[:, None] * r
        k = 3 * self.w.shape[1]         # 12 for a pair, 6 for a segment on an obstacle
        G = -(self.w[:, :, None] * F[:, None, :]).reshape(-1, k)
        eps = self.law.slip_tolerance
        C = m[:, None, None] * dr + (2 * mollifier_slope(y2) / eps**3)[:, None, None] \
            * r[:, :, None] * u[:, None, :]
        K = self.bound[:, None, None] * np.einsum("mij,mjk->mik", C, self.T)
        ww = self.w[:, :, None] * self.w[:, None, :]
        H = np.einsum("mkl,mij->mkilj", ww, K).reshape(-1, k, k)
        return self.nodes, G, H

    def power(self, V: np.ndarray) -> tuple[float, float]:
        """(dissipation rate mu lambda phi |u| summed over the pairs, the sum of the
        friction forces' magnitudes |F|) at the nodes' velocities V."""
        u, _, m = self.slip(V)
        F = (self.bound * m)[:, None] * self.resisted(u)[0]
        return (float(np.einsum("mi,mi->", F, u)),
                float(np.linalg.norm(F, axis=1).sum()))
