"""Triangle surfaces for the mesh obstacle's tests (rod/triangle_mesh.py): an icosphere
(vertices on the sphere, faces inside it by at most the sagitta), a box, and their files
written as ASCII STL, binary STL and OBJ."""

from __future__ import annotations

import numpy as np


def icosphere(level: int, radius: float = 1.0, centre=(0.0, 0.0, 0.0)):
    """(vertices, triangles) of the icosahedron subdivided ``level`` times, its vertices
    on the sphere, counter-clockwise seen from outside."""
    p = (1 + 5**0.5) / 2
    V = [(-1, p, 0), (1, p, 0), (-1, -p, 0), (1, -p, 0), (0, -1, p), (0, 1, p), (0, -1, -p),
         (0, 1, -p), (p, 0, -1), (p, 0, 1), (-p, 0, -1), (-p, 0, 1)]
    T = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(level):
        middle, new = {}, []

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in middle:
                m = V[i] + V[j]
                V.append(m / np.linalg.norm(m))
                middle[key] = len(V) - 1
            return middle[key]
        for a, b, c in T:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        T = new
    return np.asarray(centre) + radius * np.array(V), np.array(T)


def sagitta(vertices, triangles, radius: float) -> float:
    """The largest depth of a face below the sphere through its vertices: R - the
    distance of the face's plane from the centre (at its circumcentre), over the faces."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    centre = vertices.mean(axis=0)
    return float(np.max(radius - np.abs(np.einsum("ij,ij->i", a - centre, n))))


def box(half=(1.0, 1.0, 1.0), centre=(0.0, 0.0, 0.0)):
    """(vertices, triangles) of the box |x_i - c_i| <= half_i, 12 triangles."""
    corners = np.array([[(-1) ** (k >> 2 & 1 ^ 1), (-1) ** (k >> 1 & 1 ^ 1),
                         (-1) ** (k & 1 ^ 1)] for k in range(8)], float)
    T = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                  (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)])
    return np.asarray(centre) + corners * np.asarray(half), T


def boxes(centres, half: float, turn: float = 0.0):
    """(vertices, triangles) of cubes of half-side ``half`` turned by ``turn`` about e_2,
    centred at ``centres`` (k, 3): one closed surface of 12 k sharp edges (the broad
    phase of rod/obstacle_segments.py)."""
    V, T = box((half,) * 3)
    c, s = np.cos(turn), np.sin(turn)
    V = V @ np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    return (np.concatenate([V + centre for centre in np.asarray(centres, float)]),
            np.concatenate([T + 8 * k for k in range(len(centres))]))


def grid(count: int, spacing: float, centre=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(count, 3) points on a square grid in the plane x = centre_x, ``spacing`` apart,
    about ``centre``."""
    side = int(np.ceil(np.sqrt(count)))
    k = np.arange(count)
    return np.asarray(centre) + spacing * np.column_stack(
        [0 * k, k % side - (side - 1) / 2, k // side - (side - 1) / 2])


def write_stl_ascii(path, V, T) -> None:
    lines = ["solid test"]
    for t in T:
        lines += ["facet normal 0 0 0", "outer loop",
                  *(f"vertex {float(V[i][0])!r} {float(V[i][1])!r} {float(V[i][2])!r}" for i in t),
                  "endloop", "endfacet"]
    path.write_text("\n".join(lines + ["endsolid test"]) + "\n")


def write_stl_binary(path, V, T) -> None:
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)),
                       ("attribute", "<u2")])
    data = np.zeros(len(T), record)
    data["corners"] = np.asarray(V)[np.asarray(T)]
    path.write_bytes(b"solid binary file".ljust(80, b" ")
                     + np.uint32(len(T)).tobytes() + data.tobytes())


def write_obj(path, V, T) -> None:
    path.write_text("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in V)
                    + "".join(f"f {a + 1} {b + 1}/0 {c + 1}//0\n" for a, b, c in T))


def prism(n: int, radius: float, length: float, phase: float = 0.0):
    """(vertices, triangles) of the closed prism on the regular n-gon inscribed in the
    circle of ``radius`` about the axis e_2 (corners at angles phase + 2 pi k / n in the
    (z, x) plane), |y| <= length / 2, 4 n triangles."""
    angle = phase + 2 * np.pi * np.arange(n) / n
    ring = np.stack([radius * np.sin(angle), np.zeros(n), radius * np.cos(angle)], 1)
    V = np.vstack([ring + (0, -length / 2, 0), ring + (0, length / 2, 0),
                   [(0, -length / 2, 0), (0, length / 2, 0)]])
    k, k1 = np.arange(n), (np.arange(n) + 1) % n
    T = np.vstack([np.stack([k, k1, n + k1], 1), np.stack([k, n + k1, n + k], 1),
                   np.stack([np.full(n, 2 * n), k1, k], 1),
                   np.stack([np.full(n, 2 * n + 1), n + k, n + k1], 1)])
    return V, T
