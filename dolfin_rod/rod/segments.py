"""The rod's centre line as segments (one per cell): closest points of segment pairs, the
pairs near each other (broad phase), and the cheap check at output times that no two
non-neighbouring segments passed through each other (issue 26; docs/contact.md).

Narrow phase: the closest points of two segments p(s) = p0 + s (p1 - p0), q(t) = q0 +
t (q1 - q0), s, t in [0, 1] (Ericson, Real-Time Collision Detection, 5.1.9: the
unconstrained minimiser clamped to the square, then the other parameter re-solved and
clamped), parallel segments included.  Broad phase: scipy's cKDTree on the segments'
midpoints, O(N log N): two segments closer than d have midpoints closer than d + the
longest segment; the pass-through check of a rod of at most ``FEW`` segments compares
every pair instead (no scipy import: 0.3-0.6 s of a run, issue 30).  Neighbours along a
rod (closer in s than ``exclusion``) are never a pair: a rod of radius r cannot bend back
onto itself within an arc of pi r.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

FEW = 128      # segments whose every pair the pass-through check compares (8128 pairs)


def closest_points(p0, p1, q0, q1):
    """Parameters (s, t) in [0, 1] of the closest points of segment pairs ((n, 3) each)
    and their distances; a second segment of length 0 (q0 = q1) is a point (t = 0)."""
    d1, d2, w = p1 - p0, q1 - q0, p0 - q0
    a, e = np.einsum("ij,ij->i", d1, d1), np.einsum("ij,ij->i", d2, d2)
    b, c, f = (np.einsum("ij,ij->i", d1, d2), np.einsum("ij,ij->i", d1, w),
               np.einsum("ij,ij->i", d2, w))
    denom = a * e - b * b
    parallel = denom <= 1e-12 * a * e
    point = e == 0.0            # q a point (a sphere's centre, obstacle_segments.py)
    s = np.where(parallel, np.where(point, np.clip(-c / a, 0.0, 1.0), 0.0),
                 np.clip((b * f - c * e) / np.where(parallel, 1.0, denom), 0.0, 1.0))
    t = np.where(point, 0.0, (b * s + f) / np.where(point, 1.0, e))
    s = np.where(t < 0.0, np.clip(-c / a, 0.0, 1.0),
                 np.where(t > 1.0, np.clip((b - c) / a, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    gap = (p0 + s[:, None] * d1) - (q0 + t[:, None] * d2)
    return s, t, np.sqrt(np.einsum("ij,ij->i", gap, gap))


def exclusion(radius: float, gap: float, h: float) -> float:
    """The distance in s within which segments of one rod are neighbours, not a pair
    (pair_contact.py): pi (r + delta) + h, h the longest cell."""
    return math.pi * (radius + gap) + h


def exclusion_problem(radius: float, gap: float, h: float, shortest: float) -> str | None:
    """Why self-contact cannot work on rods whose shortest is ``shortest`` long (the
    exclusion covers it: no pair would be left; its message names contact.radius), or
    None."""
    reach = exclusion(radius, gap, h)
    if reach < shortest:
        return None
    return (f"contact.radius = {radius:g}: self-contact excludes neighbours closer along "
            f"the rod than pi (r + delta) + h = {reach:.4g}, which is not shorter than the "
            f"rod ({shortest:g}): a smaller radius or more cells")


class PairOverlap(ValueError):
    """Two segments whose capsules overlap at t = 0 (``key``: contact.self for segments
    of one rod, contact.between_rods for two rods)."""

    def __init__(self, reason: str, key: str):
        super().__init__(reason)
        self.key = key

    @classmethod
    def at(cls, names: tuple[str, str], point, g: float, radius: float,
           same_rod: bool) -> "PairOverlap":
        """The overlap g <= 0 of the segments of ``names`` ("the rod at s = ...", "rod b
        at s = ...": their midpoints) near ``point``."""
        where = ", ".join(f"{v:.4g}" for v in point)
        return cls(f"the initial state: segments of {names[0]} and {names[1]}, near "
                   f"({where}): overlap by {-g:.3g} at t = 0 (their centre lines are closer "
                   f"than 2 contact.radius = {2 * radius:g}): start them farther apart",
                   "contact.self" if same_rod else "contact.between_rods")


def chord_reaches_round(h, radius: float, reach: float):
    """Whether a straight chord of length h across a round obstacle of radius R (a sphere,
    a cylinder's side), the obstacle midway, touches it while both its ends are farther
    than ``reach`` from its surface: h^2 >= 4 reach (2 R + reach) (the ends then lie
    sqrt(h^2 / 4 + R^2) >= R + reach from the centre): nodes h apart whose barrier
    reaches ``reach`` cannot hold a rod across it (contact.on_segments)."""
    return np.asarray(h) ** 2 >= 4 * reach * (2 * radius + reach)


def on_segments(contact: str, shape: str, radius: float, reach: float, h: float,
                turn=()) -> bool:
    """Whether an obstacle's barrier acts on the rod's segments (rod/contact.on_segments:
    an obstacle's keys contact, shape, radius; the barrier's reach r + delta,
    the longest cell h; a mesh's convex edges' ``turn``, triangle_mesh.convex_edges):
    "segments", or "auto" for a sphere or cylinder that ``chord_reaches_round`` and a
    mesh with an edge that ``chord_reaches_edge`` (its sharp edges then act on the
    segments, its faces on the nodes; numpy only: `dolfin-rod check` says it too)."""
    if contact != "auto":
        return contact == "segments"
    if shape == "mesh":
        return bool(np.any(chord_reaches_edge(h, turn, reach)))
    return shape in ("sphere", "cylinder") and bool(chord_reaches_round(h, radius, reach))


def chord_reaches_edge(h, turn, reach: float):
    """The same for a convex edge whose faces' normals turn by ``turn``: the chord across
    it makes the angle turn / 2 with each face, its ends (h / 2) sin(turn / 2) from them
    (obstacle_shapes.fixed_segments)."""
    return 0.5 * np.asarray(h) * np.sin(np.asarray(turn) / 2) >= reach


def near_pairs(p0, p1, mid_s, distance: float, exclusion: float,
               tree: bool = True) -> np.ndarray:
    """(m, 2) index pairs i < j of segments (rows of p0, p1; parameters mid_s of their
    midpoints) whose closest points are nearer than ``distance``, excluding pairs nearer
    than ``exclusion`` in s.  Candidates: midpoints nearer than ``distance`` + the longest
    segment, by scipy's cKDTree, or without ``tree`` by comparing every pair (the same
    pairs, in the order i, then j)."""
    mid = 0.5 * (p0 + p1)
    longest = np.sqrt(np.max(np.einsum("ij,ij->i", p1 - p0, p1 - p0), initial=0.0))
    if tree:
        from scipy.spatial import cKDTree        # imported at the first tree (0.3-0.6 s)
        pairs = cKDTree(mid).query_pairs(distance + longest, output_type="ndarray")
    else:
        pairs = _pairs_within(mid, distance + longest)
    pairs = pairs[np.abs(mid_s[pairs[:, 0]] - mid_s[pairs[:, 1]]) >= exclusion]
    if len(pairs) == 0:
        return pairs.reshape(0, 2)
    i, j = pairs[:, 0], pairs[:, 1]
    return pairs[closest_points(p0[i], p1[i], p0[j], p1[j])[2] < distance]


def _pairs_within(points, reach: float) -> np.ndarray:
    """(m, 2) index pairs i < j of points at most ``reach`` apart, every pair compared."""
    i, j = np.triu_indices(len(points), 1)
    gap = points[i] - points[j]
    near = np.einsum("ij,ij->i", gap, gap) <= reach * reach
    return np.column_stack([i[near], j[near]])


def crossing_sides(p0, p1, pairs) -> np.ndarray:
    """Per pair the side on which segment j passes segment i: the sign of
    (q(t) - p(s)) . (p1 - p0) x (q1 - q0) at the closest points; it flips when the two
    segments pass through each other."""
    i, j = pairs[:, 0], pairs[:, 1]
    s, t, _ = closest_points(p0[i], p1[i], p0[j], p1[j])
    d1, d2 = p1[i] - p0[i], p1[j] - p0[j]
    gap = (p0[j] + t[:, None] * d2) - (p0[i] + s[:, None] * d1)
    return np.sign(np.einsum("ij,ij->i", gap, np.cross(d1, d2)))


def joint_distances(mid_s: np.ndarray, joints) -> list[np.ndarray]:
    """Per joint point (the nodes (s_a, s_b) of the joints, those sharing a node merged:
    one place in space) each segment's distance in s (its midpoint's, ``mid_s``) to the
    nearest of its nodes: two segments whose distances add up to less than the exclusion
    are neighbours through the joint (as within a rod), no pair."""
    groups: list[set] = []
    for joint in joints:
        linked = [g for g in groups if g & set(joint)]
        merged = set(joint).union(*linked)
        groups = [g for g in groups if g not in linked] + [merged]
    return [np.min(np.abs(mid_s[:, None] - np.array(sorted(g))[None, :]), axis=1)
            for g in groups]


class PassThroughCheck:
    """At output times: did two non-neighbouring segments pass through each other since
    the last check?  Pairs nearer than ``distance`` at both checks whose crossing side
    flipped (not neighbours through ``joints``, joint_distances); the first such event is
    reported once per run (a warning on rank 0 naming the time and the two places s,
    with several rods (``layout``, a RodLayout; ``names``: each of its rods' name, a
    rod split at its kinks named as the user's rod) the rods and s on each).  Cost: one gather of the centre line, one midpoint tree (none for
    one rod while every segment points within 60 degrees of the mean direction: such a
    line cannot meet itself; two rods can, crossing at 90 degrees).  Pairs that segment
    contact keeps apart (``covered``: (contact.self, contact.between_rods)) are left to
    it: its steps cannot cross them, and two parallel segments in contact have no
    crossing side to follow."""

    def __init__(self, x, distance: float, exclusion: float, hint: str, layout=None,
                 names=(), joints=(), covered=(False, False)):
        space = x.function_space
        self.x, self.comm, self.hint = x, space.mesh.comm, hint
        self.layout = None if layout is None or layout.single else layout
        self.names, self.joints = list(names), list(joints)
        self.distance, self.exclusion = distance, exclusion
        n_cells = space.mesh.topology.index_map(1).size_local
        dofs = space.dofmap.list[:n_cells]
        self.ends = dofs[:, 0], dofs[:, 1]
        s_nodes = space.tabulate_dof_coordinates()[:, 0]
        self.reference = [np.outer(s_nodes[d], (0.0, 0.0, 1.0)) for d in self.ends]
        self.mid_s = s_nodes[dofs].mean(axis=1)
        self.nodes = self.x.x.array.reshape(-1, 3)      # a view
        self.previous: dict | None = None
        self.warned = False
        self.covered = covered
        self.owner = (np.zeros(len(self.mid_s), int) if self.layout is None
                      else self.layout.along(self.mid_s)[0])
        one_rod = self.layout is None or len(self.layout.rods) == 1
        self.needed = not (covered[0] and (one_rod or covered[1]))   # same on every rank

    def _segments(self):
        """(p0, p1, s of the midpoints, rod) of every cell, on rank 0 (None elsewhere)."""
        p0, p1 = (self.nodes[d] + X for d, X in zip(self.ends, self.reference))
        if self.comm.size == 1:
            return p0, p1, self.mid_s, self.owner
        gathered = self.comm.gather((p0, p1, self.mid_s, self.owner), root=0)
        if gathered is None:
            return None
        return tuple(np.concatenate([g[k] for g in gathered]) for k in range(4))

    def __call__(self, t: float) -> None:
        if not self.needed:
            return
        segments = self._segments()
        if segments is None or self.warned:
            return
        p0, p1, mid_s, owner = segments
        tangents = p1 - p0
        mean = tangents.sum(axis=0)
        cosines = (tangents @ mean) ** 2 / np.einsum("ij,ij->i", tangents, tangents)
        if self.layout is None and np.all(cosines > 0.25 * (mean @ mean)) \
                and np.all(tangents @ mean > 0):
            self.previous = None        # every tangent within 60 degrees of the mean
            return
        pairs = near_pairs(p0, p1, mid_s, self.distance, self.exclusion,
                           tree=len(mid_s) > FEW)
        for near in joint_distances(mid_s, self.joints):    # neighbours through a joint
            pairs = pairs[near[pairs[:, 0]] + near[pairs[:, 1]] >= self.exclusion]
        if any(self.covered):
            same = owner[pairs[:, 0]] == owner[pairs[:, 1]]
            pairs = pairs[~((same & self.covered[0]) | (~same & self.covered[1]))]
        sides = dict(zip(map(tuple, pairs), crossing_sides(p0, p1, pairs)))
        passed = [pair for pair, side in sides.items() if self.previous is not None
                  and self.previous.get(pair, side) * side < 0]
        self.previous = sides
        if passed:
            self.warned = True
            warnings.warn(f"at t = {t:.6g} {self._places(*(mid_s[k] for k in passed[0]))} "
                          f"({self.hint})", PassThroughWarning, stacklevel=2)

    def _places(self, a: float, b: float) -> str:
        """Who passed through whom at the parameters a < b of the two segments."""
        if self.layout is None:
            return f"the rod passed through itself near s = {a:.4g} and s = {b:.4g}"
        ka, kb = self.layout.rod_of([a, b])
        offsets = self.layout.offsets or (0.0,) * len(self.names)
        sa, sb = (s - self.layout.starts[k] + offsets[k] for s, k in ((a, ka), (b, kb)))
        name_a, name_b = self.names[ka], self.names[kb]
        if len(set(self.names)) == 1:
            return f"the rod passed through itself near s = {sa:.4g} and s = {sb:.4g}"
        if name_a == name_b:
            return (f"rod {name_a} passed through itself near s = {sa:.4g} and "
                    f"s = {sb:.4g}")
        return f"rod {name_a} near s = {sa:.4g} and rod {name_b} near s = {sb:.4g} " \
               "passed through each other"


class PassThroughWarning(UserWarning):
    """Two non-neighbouring segments of a rod passed through each other."""
