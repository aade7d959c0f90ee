"""Segment contact on a C^1 centre line (issue 26; docs/contact.md, "Smooth pairs"):
each segment's curve is the Catmull-Rom cubic through its two nodes with the tangents
(X_{k+1} - X_{k-1}) / 2 at its nodes (a phantom node X_{-1} = 2 X_0 - X_1 at a rod's
end), so c_i(u) = sum_k phi_k(u) X_{n_k} over the four nodes n = (prev, a, b, next),
and the curves of a rod join with a continuous tangent.  The interpolation reproduces
quadratics: a contact force at u is spread over the nodes with weights whose second
moment about the contact point vanishes, so the discrete rod's compliance under it has
no dip between the nodes (the P1 segment's weights (1 - u, u) have the second moment
u (1 - u) h^2, the dip that makes a crossing inside a segment an unstable equilibrium).

A pair of segments (i, j) carries the energy kappa w_ij b(d - 2 r) of the distance d
of the two curves' closest points over its parameter square, counted only where that
minimum is a local minimum of the two whole curves' distance: a minimiser on an edge
the square shares with a neighbouring pair's (a segment's end that is not a rod's end)
belongs to that neighbour (its minimum is lower, or the same point).  So every close
approach of the curves counts once wherever it lies along the segments, and its energy
is C^1 as the contact point crosses a node (the curves' tangents are continuous; the
curvature, so the Hessian, jumps there).

d(Y) (Y: the pair's eight stencil nodes) is the value of min |D(s, t)| with D =
c_i(s) - c_j(t) = sum_m W_m(s, t) Y_m; f = |D|^2 / 2 has the gradient W_m D (envelope
theorem) and the Hessian f_YY - f_Ya f_aa^-1 f_aY over the free parameters a, with
f_YY = W W^T (x) I, f_Ys = W_s (x) D + W (x) D_s, f_aa = [[D_s.D_s + D.D_ss, D_s.D_t],
[D_s.D_t, D_t.D_t + D.D_tt]].
"""

from __future__ import annotations

import numpy as np

from .barrier import barrier_derivatives

TIE = 1e-9          # a minimiser within this of a shared node (in u) goes to the pair after it
NEWTON = 30         # projected Newton iterations of the closest points (from P1's)
LIPSCHITZ = 1.25    # max_u sum_k |phi_k(u)|: |c_i(u)| moves at most this times its nodes'
                    # largest move (1/16 + 9/16 + 9/16 + 1/16 at u = 1/2; ends: less)


def catmull_rom(u):
    """phi_k(u), phi_k'(u), phi_k''(u), (m, 4) each, of the uniform Catmull-Rom cubic."""
    u = np.asarray(u, float)[:, None]
    c = np.array([[0.0, -1.0, 2.0, -1.0], [2.0, 0.0, -5.0, 3.0],
                  [0.0, 1.0, 4.0, -3.0], [0.0, 0.0, -1.0, 1.0]]).T / 2   # (power, k)
    powers = np.hstack([np.ones_like(u), u, u * u, u**3])
    d1 = np.hstack([np.zeros_like(u), np.ones_like(u), 2 * u, 3 * u * u])
    d2 = np.hstack([np.zeros_like(u), np.zeros_like(u), 2 * np.ones_like(u), 6 * u])
    return powers @ c, d1 @ c, d2 @ c


class Stencils:
    """Per segment of a centre line (``ends`` (n, 2) global nodes, ``rod`` (n,), in order
    along each rod) its four nodes (prev, a, b, next), the matrix F (4, 4) folding a rod
    end's phantom node into the others (weights phi @ F), and its neighbours along the
    rod (-1 at a rod's end)."""

    def __init__(self, ends: np.ndarray, rod: np.ndarray):
        n = len(ends)
        k = np.arange(n)
        joined = (k[1:] < n) & (rod[1:] == rod[:-1]) & (ends[1:, 0] == ends[:-1, 1])
        self.prev = np.where(np.concatenate([[False], joined]), k - 1, -1)
        self.next = np.where(np.concatenate([joined, [False]]), k + 1, -1)
        self.nodes = np.column_stack([
            np.where(self.prev >= 0, ends[np.maximum(self.prev, 0), 0], ends[:, 0]),
            ends[:, 0], ends[:, 1],
            np.where(self.next >= 0, ends[np.minimum(self.next, n - 1), 1], ends[:, 1])])
        fold = np.tile(np.eye(4), (n, 1, 1))
        start, end = self.prev < 0, self.next < 0
        fold[start, 0] = (0.0, 2.0, -1.0, 0.0)       # X_prev = 2 X_a - X_b
        fold[end, 3] = (0.0, -1.0, 2.0, 0.0)         # X_next = 2 X_b - X_a
        self.fold = fold

    def weights(self, seg: np.ndarray, u: np.ndarray):
        """(w, w', w'') (m, 4) of segments seg at parameters u: c = sum_k w_k X_nodes[k]."""
        fold = self.fold[seg]
        return tuple(np.matmul(phi[:, None, :], fold)[:, 0] for phi in catmull_rom(u))

    def deviation(self, P: np.ndarray) -> np.ndarray:
        """(n,) a bound of each segment's curve's distance from its chord: c - chord =
        phi_0 (X_p - 2 X_a + X_b) + phi_3 (X_a - 2 X_b + X_n), |phi_0| + |phi_3| <=
        u (1 - u) / 2 <= 1/8 (the folded phantom's second differences are 0)."""
        X = P[self.nodes]
        second = [X[:, 0] - 2 * X[:, 1] + X[:, 2], X[:, 1] - 2 * X[:, 2] + X[:, 3]]
        second[0][self.prev < 0] = 0.0
        second[1][self.next < 0] = 0.0
        return np.maximum(*(np.linalg.norm(v, axis=1) for v in second)) / 8


def closest(Y: np.ndarray, wa, wb, s: np.ndarray, t: np.ndarray):
    """Closest points (s, t) in [0, 1]^2 of the pairs' curves, their distance d and the
    1-D Newton estimates (sigma_s, sigma_t) of the stationary point (``counted``), Y
    (m, 8, 3) their stencil nodes, wa, wb callables (rows, u) -> (w, w', w'') of the
    rows' first and second segments, by projected Newton from (s, t) (P1's closest
    points): a parameter at its bound with the gradient pushing outwards is held there
    and the other solved alone; the pairs not yet converged iterate on."""
    s, t = np.array(s, float), np.array(t, float)
    rows = np.arange(len(s))
    for _ in range(NEWTON):
        if not len(rows):
            break
        ss, tt = s[rows], t[rows]
        D, Ds, Dt, Dss, Dtt = _frames(Y[rows], wa(rows, ss), wb(rows, tt))
        gs, gt = _dot(D, Ds), _dot(D, Dt)
        a, b, e = _dot(Ds, Ds) + _dot(D, Dss), _dot(Ds, Dt), _dot(Dt, Dt) + _dot(D, Dtt)
        hold_s = ((ss <= 0) & (gs > 0)) | ((ss >= 1) & (gs < 0))
        hold_t = ((tt <= 0) & (gt > 0)) | ((tt >= 1) & (gt < 0))
        det = a * e - b * b
        both = ~hold_s & ~hold_t & (det > 1e-14 * np.maximum(a * e, 1e-300)) & (a > 0)
        ds = np.where(both, -(e * gs - b * gt) / np.where(both, det, 1.0), 0.0)
        dt = np.where(both, -(a * gt - b * gs) / np.where(both, det, 1.0), 0.0)
        only_s = ~both & ~hold_s & (a > 0)
        only_t = ~both & ~hold_t & ~only_s & (e > 0)
        ds = np.where(only_s, -gs / np.where(only_s, a, 1.0), ds)
        dt = np.where(only_t, -gt / np.where(only_t, e, 1.0), dt)
        # steps of at most half the square: a pair far from its minimum converges monotonically
        s_new = np.clip(ss + np.clip(ds, -0.5, 0.5), 0.0, 1.0)
        t_new = np.clip(tt + np.clip(dt, -0.5, 0.5), 0.0, 1.0)
        moving = np.abs(s_new - ss) + np.abs(t_new - tt) > 1e-14
        s[rows], t[rows] = s_new, t_new
        rows = rows[moving]
    every = np.arange(len(s))
    D, Ds, Dt, Dss, Dtt = _frames(Y, wa(every, s), wb(every, t))
    a, e = _dot(Ds, Ds) + _dot(D, Dss), _dot(Dt, Dt) + _dot(D, Dtt)
    sigma_s = s - _dot(D, Ds) / np.where(a > 0, a, np.inf)
    sigma_t = t - _dot(D, Dt) / np.where(e > 0, e, np.inf)
    return s, t, np.sqrt(_dot(D, D)), sigma_s, sigma_t


def counted(sigma, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Whether a pair's minimiser belongs to its square in one parameter: sigma, the
    parameter's 1-D Newton estimate of the curves' stationary point (beyond the square
    where the minimum is clamped to an edge), lies in [0, 1) up to TIE where the
    square has a neighbouring pair before (at 0) or after (at 1); a minimiser exactly
    on a shared node so belongs to the pair after it, once (the two squares compute the
    same point with the same tangents)."""
    return (~before | (sigma >= -TIE)) & (~after | (sigma < 1 - TIE))


def free(u: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Whether a counted pair's parameter u is free: inside (0, 1), or on an edge shared
    with a neighbouring pair (``counted`` gave it the minimiser on a node: the curve
    goes on across it)."""
    return ((u > 0) | before) & ((u < 1) | after)


def _dot(u, v):
    return np.einsum("mi,mi->m", u, v)


def _frames(Y, wa, wb):
    """D, D_s, D_t, D_ss, D_tt of the pairs at the weights (w, w', w'') of each side."""
    A, B = Y[:, :4], Y[:, 4:]

    def at(w, X):
        return np.matmul(w[:, None, :], X)[:, 0]
    return (at(wa[0], A) - at(wb[0], B), at(wa[1], A), -at(wb[1], B), at(wa[2], A),
            -at(wb[2], B))


def smooth_pair_energy(Y, wa, wb, s, t, free, radius: float, gap: float, stiffness,
                       weights, order: int = 2):
    """Energy (m,), gradient (m, 24) and (order 2) Hessian (m, 24, 24) of pairs of curve
    segments, Y (m, 8, 3) their stencil nodes (wa, wb: as for ``closest``), at their
    closest points (s, t)
    (``closest``): E = kappa w b(d - 2 r).  free (2, m): whether s, t are free
    parameters of the minimum (inside (0, 1), or on an edge the curve continues across:
    a minimiser on a shared node, where the pair counts it); the others are held at
    their bound (a rod's end)."""
    m = len(s)
    (Wa, Wa1, Wa2), (Wb, Wb1, Wb2) = wa(np.arange(m), s), wb(np.arange(m), t)
    D, Ds, Dt, Dss, Dtt = _frames(Y, (Wa, Wa1, Wa2), (Wb, Wb1, Wb2))
    d = np.sqrt(_dot(D, D))
    W = np.hstack([Wa, -Wb])                                      # (m, 8)
    grad = (W[:, :, None] * (D / d[:, None])[:, None, :]).reshape(m, 24)
    b, b1, b2 = barrier_derivatives(d - 2 * radius, gap)
    k = stiffness * np.asarray(weights, float)
    E, G = k * b, (k * b1)[:, None] * grad
    if order < 2:
        return E, G, None
    zero = np.zeros_like(Wa)
    Ws, Wt = np.hstack([Wa1, zero]), np.hstack([zero, -Wb1])
    # f_Ya (m, 2, 24): W_a (x) D + W (x) D_a
    fYa = np.stack([(Ws[:, :, None] * D[:, None] + W[:, :, None] * Ds[:, None]),
                    (Wt[:, :, None] * D[:, None] + W[:, :, None] * Dt[:, None])],
                   axis=1).reshape(m, 2, 24)
    a11, a12, a22 = _dot(Ds, Ds) + _dot(D, Dss), _dot(Ds, Dt), _dot(Dt, Dt) + _dot(D, Dtt)
    free_s, free_t = free
    both = free_s & free_t
    det = np.where(both, a11 * a22 - a12 * a12, 1.0)
    inv = np.zeros((m, 2, 2))
    inv[:, 0, 0] = np.where(both, a22 / det, np.where(free_s & ~both, 1 / np.where(
        free_s & ~both, a11, 1.0), 0.0))
    inv[:, 1, 1] = np.where(both, a11 / det, np.where(free_t & ~both, 1 / np.where(
        free_t & ~both, a22, 1.0), 0.0))
    inv[:, 0, 1] = inv[:, 1, 0] = np.where(both, -a12 / det, 0.0)
    hess_f = np.zeros((m, 8, 3, 8, 3))
    WW = W[:, :, None] * W[:, None, :]
    for i in range(3):
        hess_f[:, :, i, :, i] = WW                      # f_YY = W W^T (x) I
    hess_f = hess_f.reshape(m, 24, 24) - np.matmul(np.transpose(fYa, (0, 2, 1)),
                                                   np.matmul(inv, fYa))
    hess_d = (hess_f - grad[:, :, None] * grad[:, None, :]) / d[:, None, None]
    H = (k * b2)[:, None, None] * grad[:, :, None] * grad[:, None, :] \
        + (k * b1)[:, None, None] * hess_d
    return E, G, H
