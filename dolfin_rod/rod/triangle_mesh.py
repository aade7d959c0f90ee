"""Triangle-mesh obstacles (issue 26; docs/contact.md): reading STL (ASCII or binary) and
OBJ files with numpy, checking the surface, and the signed distance of points to it with
the closest feature (a face, an edge or a vertex) that a node's gap follows.

The signed distance of p is d(p) = s |p - q(p)|, q(p) the closest point of the surface
and s the sign of (p - q) . N, N the angle-weighted pseudo-normal of the feature that
holds q (the face's normal; an edge's: the sum of its faces'; a vertex's: its faces'
normals weighted by their angles there): exact for a closed, outward-oriented surface
(Baerentzen & Aanaes 2005).  An open surface (e.g. a terrain, a plane of two triangles)
is one-sided: the side its normals point to is outside, the points behind it whose
closest point is inside its border are inside, every point closest to its border is
outside (d jumps from -D to D where the region behind the surface meets the border's).

Within the region of points closest to one feature d is that feature's distance: the
plane of a face (n . (p - a), linear), the line of an edge, or a vertex.  The contact
law (contact.py) takes d at the nodes in that form, with the feature of each node found
anew at every residual evaluation (``Surface.features``): its gradient and Hessian are
then d's own, exactly, away from the regions' borders.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

FACE, EDGE, VERTEX = 0, 1, 2            # a feature's kind
MERGE = 1e-9                            # vertices closer than MERGE x size are one
DEGENERATE = 1e-12                      # a triangle with area < DEGENERATE x size^2
ALL_PAIRS = 200_000                     # (point, triangle) pairs compared all without
                                        # a tree (Surface.candidates)


class MeshError(ValueError):
    """A mesh that is no obstacle surface; ``key`` the scene key at fault (file,
    vertices or triangles)."""

    def __init__(self, key: str, reason: str):
        super().__init__(reason)
        self.key = key


# -- files ---------------------------------------------------------------------------------

def read_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3), triangles (m, 3)) of an STL (ASCII or binary) or OBJ file
    (OBJ polygons split into fans of triangles); MeshError("file", ...) otherwise."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise MeshError("file", f"cannot read {str(path)!r}: {err.strerror}") from None
    suffix = path.suffix.lower()
    try:
        if suffix == ".stl":
            corners = _stl(data)
            return _merge(corners.reshape(-1, 3), corners.shape[0])
        if suffix == ".obj":
            return _obj(data.decode("utf-8", "replace"))
    except (ValueError, IndexError) as err:
        raise MeshError("file", f"{str(path)!r} is not a valid {suffix[1:].upper()} file: "
                                f"{err}") from None
    raise MeshError("file", f"{str(path)!r}: the file's extension must be .stl or .obj, "
                            f"got {suffix or 'none'!r}")


def _stl(data: bytes) -> np.ndarray:
    """(m, 3, 3) the triangles' corners of an STL file: binary if its length is 84 + 50 m
    with m its header's count (an ASCII file may start with 'solid' too), else ASCII."""
    if len(data) >= 84:
        m = int(np.frombuffer(data, "<u4", 1, 80)[0])
        if len(data) == 84 + 50 * m:
            record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)),
                               ("attribute", "<u2")])
            return np.frombuffer(data, record, m, 84)["corners"].astype(float)
    words = data.decode("ascii", "replace").split()
    where = [i for i, w in enumerate(words) if w == "vertex"]
    if not where or len(where) % 3:
        raise ValueError(f"{len(where)} 'vertex' lines (3 per facet)")
    return np.array([[float(words[i + k]) for k in (1, 2, 3)] for i in where]).reshape(-1, 3, 3)


def _obj(text: str) -> tuple[np.ndarray, np.ndarray]:
    vertices, triangles = [], []
    for line in text.splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            ids = [int(p.split("/")[0]) for p in parts[1:]]
            ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]
            if len(ids) < 3:
                raise ValueError(f"a face of {len(ids)} vertices")
            triangles += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
    return np.array(vertices, float).reshape(-1, 3), np.array(triangles, int).reshape(-1, 3)


def _merge(points: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """One vertex for corners that coincide (to MERGE of the mesh's size): an STL file
    repeats each corner in every triangle that holds it."""
    if not len(points):
        return points, np.zeros((0, 3), int)
    size = float(np.ptp(points, axis=0).max()) or 1.0
    keys = np.round((points - points.min(axis=0)) / (MERGE * size)).astype(np.int64)
    _, first, index = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return points[first], index.reshape(m, 3)


def placed_surface(file=None, vertices=None, triangles=None, centre=None, rotation=None,
                   scale: float = 1.0) -> "Surface":
    """The Surface of a mesh obstacle's keys: a ``file``, or ``vertices`` and
    ``triangles`` (MeshError("file") for neither or both), placed by centre, rotation,
    scale (defaults 0, 0, 1)."""
    if (file is None) == (vertices is None or triangles is None):
        raise MeshError("file", "a mesh needs a file, or vertices and triangles (not both)")
    V, T = read_mesh(file) if file is not None else (vertices, triangles)
    zero = (0.0, 0.0, 0.0)
    return Surface(V, T, zero if centre is None else centre,
                   zero if rotation is None else rotation, scale)


# -- the surface ---------------------------------------------------------------------------

def rotation_matrix(rotation) -> np.ndarray:
    """R of the rotation vector (Rodrigues)."""
    theta = np.asarray(rotation, float)
    angle = np.linalg.norm(theta)
    if angle == 0:
        return np.eye(3)
    k = theta / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


class Surface:
    """A checked triangle surface (vertices (n, 3), triangles (m, 3) of vertex indices,
    counter-clockwise seen from outside) placed by x = centre + R(rotation) scale v.
    MeshError for degenerate triangles, an edge of more than two triangles, neighbours
    of opposite orientation, or a closed surface oriented inwards."""

    def __init__(self, vertices, triangles, centre=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0),
                 scale: float = 1.0):
        V = np.asarray(vertices, float)
        T = np.asarray(triangles)
        if V.ndim != 2 or V.shape[1] != 3 or not len(V) or not np.isfinite(V).all():
            raise MeshError("vertices", f"must be finite [x, y, z] points, got an array of "
                                        f"shape {V.shape}")
        if T.ndim != 2 or T.shape[1] != 3 or not len(T) or \
                not np.issubdtype(T.dtype, np.integer) or T.min() < 0 or T.max() >= len(V):
            raise MeshError("triangles", f"must be triples of vertex indices 0..{len(V) - 1}"
                                         f", got an array of shape {T.shape}")
        self.vertices = (np.asarray(centre, float)
                         + scale * V @ rotation_matrix(rotation).T)
        self.triangles = T.astype(np.int64)
        self._topology()

    def _topology(self) -> None:
        V, T = self.vertices, self.triangles
        a, b, c = (V[T[:, k]] for k in range(3))
        cross = np.cross(b - a, c - a)
        area2 = np.linalg.norm(cross, axis=1)
        self.size = float(np.ptp(V, axis=0).max())
        bad = np.flatnonzero(area2 <= 2 * DEGENERATE * self.size**2)
        if len(bad):
            raise MeshError("triangles", f"triangle {bad[0]} ({T[bad[0]].tolist()}) is "
                                         f"degenerate (area {area2[bad[0]] / 2:.3g}): "
                                         f"{len(bad)} such")
        self.normals = cross / area2[:, None]
        directed = np.stack([T, np.roll(T, -1, axis=1)], axis=-1).reshape(-1, 2)  # ab bc ca
        undirected = np.sort(directed, axis=1)
        edges, index, count = np.unique(undirected, axis=0, return_inverse=True,
                                        return_counts=True)
        index = index.reshape(-1)
        if count.max() > 2:
            e = edges[np.argmax(count)]
            raise MeshError("triangles", f"the edge {e.tolist()} belongs to {count.max()} "
                                         "triangles (at most 2: a surface)")
        _, twice = np.unique(directed, axis=0, return_counts=True)
        if twice.max() > 1:
            raise MeshError("triangles", "neighbouring triangles are oriented oppositely "
                                         "(an edge runs the same way in both): orient all "
                                         "counter-clockwise seen from outside")
        self.closed = bool(count.min() == 2)
        if self.closed and np.einsum("ij,ij->i", a, cross).sum() / 6 <= 0:
            raise MeshError("triangles", "the closed surface is oriented inwards (negative "
                                         "volume): orient the triangles counter-clockwise "
                                         "seen from outside")
        self.edges, self.tri_edges = edges, index.reshape(-1, 3)
        # an open surface's border: points closest to it are outside
        self.border_edges = count == 1
        self.border_vertices = np.zeros(len(V), bool)
        self.border_vertices[edges[self.border_edges].ravel()] = True
        # pseudo-normals: edges (sum of their faces'), vertices (angle-weighted)
        face_of = np.repeat(np.arange(len(T)), 3)
        self.edge_normals = np.zeros((len(edges), 3))
        np.add.at(self.edge_normals, index, self.normals[face_of])
        self.edge_normals /= np.linalg.norm(self.edge_normals, axis=1)[:, None]
        self.vertex_normals = np.zeros((len(V), 3))
        for k in range(3):
            u = V[T[:, (k + 1) % 3]] - V[T[:, k]]
            w = V[T[:, (k + 2) % 3]] - V[T[:, k]]
            cos = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1)
                                                 * np.linalg.norm(w, axis=1))
            np.add.at(self.vertex_normals, T[:, k],
                      np.arccos(np.clip(cos, -1, 1))[:, None] * self.normals)
        self.vertex_normals /= np.linalg.norm(self.vertex_normals, axis=1)[:, None]
        self.centroids = (a + b + c) / 3
        self.reach = float(np.max(np.linalg.norm(
            np.stack([a, b, c], axis=1) - self.centroids[:, None], axis=2)))
        self._tree = None

    def convex_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """(ends (m, 2, 3), turn (m,)) of the interior edges where the surface is convex
        (the second face's far corner behind the first face's plane by more than
        round-off: a flat quad's diagonal is no edge) and the angle
        between their two faces' normals (0: flat, pi / 2: a box's edge)."""
        T, V = self.triangles, self.vertices
        edge = self.tri_edges.ravel()          # entry j: triangle j // 3's edge j % 3
        order = np.argsort(edge, kind="stable")
        twice = order[~self.border_edges[edge[order]]].reshape(-1, 2)  # an edge's 2 entries
        f1, f2 = twice[:, 0] // 3, twice[:, 1] // 3
        e = self.edges[edge[twice[:, 0]]]
        far = T[f2][(T[f2] != e[:, :1]) & (T[f2] != e[:, 1:])]     # f2's third corner
        n1, n2 = self.normals[f1], self.normals[f2]
        convex = np.einsum("ij,ij->i", n1, V[far] - V[e[:, 0]]) < -1e-12 * self.size
        turn = np.arccos(np.clip(np.einsum("ij,ij->i", n1, n2), -1.0, 1.0))
        return V[e[convex]], turn[convex]

    def tree(self):
        """A cKDTree of the triangles' centroids (scipy, imported here: only mesh
        obstacles need it)."""
        if self._tree is None:
            from scipy.spatial import cKDTree
            self._tree = cKDTree(self.centroids)
        return self._tree

    def candidates(self, points: np.ndarray, tree: bool = True) -> tuple[np.ndarray,
                                                                        np.ndarray]:
        """(point, triangle) pairs that hold each point's closest triangle: those whose
        centroid is within c + R of it, c the nearest centroid's distance and R the
        largest centroid-to-corner distance (the closest triangle's centroid is within
        d + R <= c + R); found by a cKDTree, or (``tree`` False: ``dolfin-rod check``,
        without scipy's import) from every pair's distance while there are at most
        ALL_PAIRS."""
        if not tree and len(points) * len(self.centroids) <= ALL_PAIRS:
            d = np.linalg.norm(points[:, None] - self.centroids[None], axis=2)
            near = d.min(axis=1, keepdims=True)
            return np.nonzero(d <= near + self.reach * (1 + 1e-12) + 1e-300)
        tree = self.tree()
        near, _ = tree.query(points)
        balls = tree.query_ball_point(points, near + self.reach * (1 + 1e-12) + 1e-300)
        counts = np.fromiter((len(b) for b in balls), int, len(balls))
        return (np.repeat(np.arange(len(points)), counts),
                np.fromiter((t for b in balls for t in b), int, counts.sum()))

    def features(self, points, tree: bool = True) -> "Features":
        """The signed distance of each point (n, 3) and its closest feature (``tree``:
        ``candidates``)."""
        P = np.asarray(points, float).reshape(-1, 3)
        if not len(P):
            return Features(*(np.zeros(s) for s in ((0,), (0, 3), (0, 3), (0, 3))),
                            np.zeros(0, int), np.zeros(0))
        i, t = self.candidates(P, tree)
        q, kind, corner = closest_on_triangles(P[i], *(self.vertices[self.triangles[t, k]]
                                                       for k in range(3)))
        dist2 = np.einsum("ij,ij->i", P[i] - q, P[i] - q)
        order = np.lexsort((dist2, i))
        first = order[np.r_[True, i[order][1:] != i[order][:-1]]]
        i, t, q, kind, corner = i[first], t[first], q[first], kind[first], corner[first]
        T = self.triangles[t]
        # the feature: its anchor point a, its pseudo-normal N, an edge's direction e
        anchor = np.where(kind[:, None] == VERTEX, self.vertices[T[np.arange(len(t)),
                                                                    corner % 3]],
                          self.vertices[T[:, 0]])
        edge = self.tri_edges[t, corner % 3]
        ends = self.edges[edge]
        direction = self.vertices[ends[:, 1]] - self.vertices[ends[:, 0]]
        direction /= np.linalg.norm(direction, axis=1)[:, None]
        anchor = np.where(kind[:, None] == EDGE, self.vertices[ends[:, 0]], anchor)
        normal = np.select([kind[:, None] == FACE, kind[:, None] == EDGE],
                           [self.normals[t], self.edge_normals[edge]],
                           self.vertex_normals[T[np.arange(len(t)), corner % 3]])
        offset = P - q
        vertex = T[np.arange(len(t)), corner % 3]
        border = np.where(kind == EDGE, self.border_edges[edge],
                          (kind == VERTEX) & self.border_vertices[vertex])
        sign = np.where((np.einsum("ij,ij->i", offset, normal) < 0) & ~border, -1.0, 1.0)
        distance = sign * np.linalg.norm(offset, axis=1)
        return Features(distance, anchor, normal, direction, kind, sign)

    def signed_distance(self, points, tree: bool = True) -> np.ndarray:
        """d of each point (n, 3) (negative inside; ``tree``: ``candidates``)."""
        return self.features(points, tree).distance


class Features:
    """Per point: the signed distance, and its closest feature as the contact law takes
    it (contact.MeshPose): the anchor a (a point of the feature), the normal (the face's;
    an edge's or vertex's pseudo-normal), an edge's unit direction, the kind (FACE,
    EDGE, VERTEX) and the sign s of the distance (d = n . (p - a) on a face, s |p - a|
    off the edge's line or the vertex)."""

    def __init__(self, distance, anchor, normal, direction, kind, sign):
        self.distance, self.anchor, self.normal = distance, anchor, normal
        self.direction, self.kind, self.sign = direction, kind, sign


def closest_on_triangles(p, a, b, c):
    """The closest points q (n, 3) of triangles (a, b, c) to points p (each (n, 3)), the
    feature holding q (kind FACE, EDGE or VERTEX) and its place in the triangle (corner
    k = 0, 1, 2 for the vertex a, b, c or the edge ab, bc, ca); Ericson, Real-Time
    Collision Detection, 5.1.5, over arrays."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    dot = lambda u, v: np.einsum("ij,ij->i", u, v)  # noqa: E731
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), \
        dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        s_ab, s_ac = d1 / (d1 - d3), d2 / (d2 - d6)
        s_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
    cases = [(d1 <= 0) & (d2 <= 0),                                  # vertex a
             (d3 >= 0) & (d4 <= d3),                                 # vertex b
             (d6 >= 0) & (d5 <= d6),                                 # vertex c
             (vc <= 0) & (d1 >= 0) & (d3 <= 0),                      # edge ab
             (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),            # edge bc
             (vb <= 0) & (d2 >= 0) & (d6 <= 0)]                      # edge ca
    points = [a, b, c, a + s_ab[:, None] * ab, b + s_bc[:, None] * (c - b),
              a + s_ac[:, None] * ac]
    q = a + v[:, None] * ab + w[:, None] * ac
    kind, corner = np.full(len(p), FACE), np.zeros(len(p), int)
    for k in reversed(range(6)):             # the first case that holds wins
        hit = cases[k]
        q = np.where(hit[:, None], points[k], q)
        kind = np.where(hit, VERTEX if k < 3 else EDGE, kind)
        corner = np.where(hit, k % 3, corner)
    return q, kind, corner
