"""Writhe, twist and linking of a rod's centre line and frame (issue 26; Calugareanu-White
Lk = Tw + Wr, docs/contact.md), for polygons (the P1 centre line) given by their nodes.

Writhe Wr = (1/4 pi) int int (t_1 x t_2) . (r_1 - r_2) / |r_1 - r_2|^3 ds_1 ds_2 (Gauss's
double integral), exactly for a polygon as the sum over segment pairs of their signed
solid angles (Klenin & Langowski, Biopolymers 54, 2000); the linking number of two
closed polygons is the same sum over pairs of one segment of each.  Twist
Tw = (1/2 pi) int (t x u) . u_s ds of a unit normal field u: per segment the angle by
which the nodal normals, projected normal to the segment, turn about it, plus at each
node the angle between the normal transported parallel from the previous segment and
the projection on the next.
"""

from __future__ import annotations

import numpy as np


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def solid_angles(p1, p2, p3, p4) -> np.ndarray:
    """Signed solid angles Omega of segment pairs (p1 p2), (p3 p4) ((n, 3) each): Gauss's
    integral over the pair is Omega / (4 pi) (0 for coplanar pairs)."""
    r13, r14, r23, r24 = p3 - p1, p4 - p1, p3 - p2, p4 - p2
    n = [_unit(np.cross(a, b)) for a, b in ((r13, r14), (r14, r24), (r24, r23), (r23, r13))]
    omega = sum(np.arcsin(np.clip(np.einsum("ij,ij->i", n[k], n[(k + 1) % 4]), -1.0, 1.0))
                for k in range(4))
    return omega * np.sign(np.einsum("ij,ij->i", np.cross(p4 - p3, p2 - p1), r13))


def _segments(points, closed: bool):
    points = np.asarray(points, float)
    ends = np.roll(points, -1, axis=0) if closed else points[1:]
    return (points if closed else points[:-1]), ends


def writhe(points, closed: bool = False) -> float:
    """Wr of the polygon through ``points`` ((n, 3); closed: the last joined to the
    first): the sum over pairs of non-adjacent segments of Omega / (2 pi)."""
    a, b = _segments(points, closed)
    i, j = np.triu_indices(len(a), 2)
    if closed:
        keep = ~((i == 0) & (j == len(a) - 1))        # the closing segment's neighbour
        i, j = i[keep], j[keep]
    return float(np.sum(solid_angles(a[i], b[i], a[j], b[j])) / (2 * np.pi))


def linking_number(curve1, curve2) -> float:
    """Gauss's linking integral of two closed polygons (an integer up to round-off)."""
    a1, b1 = _segments(curve1, True)
    a2, b2 = _segments(curve2, True)
    i, j = np.meshgrid(np.arange(len(a1)), np.arange(len(a2)), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return float(np.sum(solid_angles(a1[i], b1[i], a2[j], b2[j])) / (4 * np.pi))


def _angle(u, v, axis):
    """Signed angle from u to v about axis (all (n, 3); u, v normal to axis)."""
    return np.arctan2(np.einsum("ij,ij->i", np.cross(u, v), axis), np.einsum("ij,ij->i", u, v))


def twist(points, normals, closed: bool = False) -> float:
    """Tw of the ribbon: the polygon through ``points`` with the unit normals (any
    vectors not along the segments, e.g. the director d_1) at its nodes."""
    a, b = _segments(points, closed)
    normals = np.asarray(normals, float)
    t = _unit(b - a)
    u_a = normals if closed else normals[:-1]
    u_b = np.roll(normals, -1, axis=0) if closed else normals[1:]
    project = lambda u, t: _unit(u - np.einsum("ij,ij->i", u, t)[:, None] * t)  # noqa: E731
    within = _angle(project(u_a, t), project(u_b, t), t)
    # at the nodes between segment k and k + 1: parallel transport of the projection on k
    t0, t1 = (t, np.roll(t, -1, axis=0)) if closed else (t[:-1], t[1:])
    u_end = project(u_b, t)[: len(t0)]
    axis = np.cross(t0, t1)
    sin, cos = np.linalg.norm(axis, axis=1), np.einsum("ij,ij->i", t0, t1)
    k = _unit(axis)
    transported = (u_end * cos[:, None] + np.cross(k, u_end) * sin[:, None]
                   + k * np.einsum("ij,ij->i", k, u_end)[:, None] * (1 - cos)[:, None])
    u_next = project(u_b[: len(t0)], t1)
    return float((within.sum() + _angle(transported, u_next, t1).sum()) / (2 * np.pi))


CLOSURE = 1e4       # the closure's straight extensions and far loop, in rod lengths


def clamped_rod_linking(points, normals, start_tangent, end_tangent) -> tuple[float, float]:
    """(Tw, Wr) of an open rod whose ends are held on one line along their tangents (a
    clamped rod twisted about its axis, e.g. a plectoneme): the polygon through
    ``points`` closed by straight extensions along -start_tangent and +end_tangent of
    CLOSURE rod lengths and a planar loop far away.  Tw is the twist of the rod's
    ribbon (``normals`` at its nodes, kept along the extensions), Wr the writhe of the
    closed curve; then Tw + Wr = Lk = the end's turns about the axis relative to the
    start (Calugareanu-White with the closure untwisting the end's rotation along the
    extension; exact for the polygon up to the closure's O(1 / CLOSURE))."""
    points, normals = np.asarray(points, float), np.asarray(normals, float)
    t0, t1 = _unit(np.asarray(start_tangent, float)), _unit(np.asarray(end_tangent, float))
    span = CLOSURE * np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1))
    below, above = points[0] - span * t0, points[-1] + span * t1
    side = _unit(np.cross(t0, normals[0]))             # the far loop's direction
    loop = [above + span * side, below + span * side]
    tw = twist(np.vstack([below, points, above]),
               np.vstack([normals[0], normals, normals[-1]]))
    wr = writhe(np.vstack([below, points, above, *loop]), closed=True)
    return tw, wr
