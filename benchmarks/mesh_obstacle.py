"""Cost of a mesh obstacle's closest features (issue 26; rod/triangle_mesh.py): the
per-evaluation work of a rod's nodes against a triangle surface, as the surface is
refined and as the rod gets more nodes.

A rod of N nodes lies along a great circle of an icosphere of radius 1 at the gap 0.01
(every node within the barrier's reach), the icosphere refined to m = 20 4^k
triangles.  Timed (best of 5): ``features`` (the broad phase, cKDTree of centroids
queried for the nearest centroid and the ball c + R, and the exact closest points of the
candidates), once per residual evaluation of a run; ``setup`` (the surface's checks,
pseudo-normals and its cKDTree, once per run).  The exponents p of cost ~ m^p and ~ N^p
between the sizes.

    ./rodenv python3 benchmarks/mesh_obstacle.py
Writes results/bench/mesh_obstacle.json.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from contact_assembly import best  # noqa: E402
from meshes import icosphere  # noqa: E402

from dolfin_rod import triangle_mesh  # noqa: E402


def main() -> None:
    rows = []
    for level in (3, 4, 5, 6):
        V, T = icosphere(level)
        for n in (100, 1000, 10000):
            phi = np.linspace(0, np.pi, n)
            P = 1.01 * np.stack([np.cos(phi), np.sin(phi), 0 * phi], 1)
            surface = triangle_mesh.Surface(V, T)
            setup = best(lambda: triangle_mesh.Surface(V, T).tree())
            features = best(lambda: surface.features(P))
            rows.append({"triangles": len(T), "nodes": n, "setup_s": setup,
                         "features_s": features,
                         "per_node_us": 1e6 * features / n})
    def exponent(key, fixed, value):
        sel = [r for r in rows if r[fixed] == value]
        x = np.log([r[key] for r in sel])
        return float(np.polyfit(x, np.log([r["features_s"] for r in sel]), 1)[0])
    out = {"rows": rows,
           "exponent_in_triangles_at_1000_nodes": exponent("triangles", "nodes", 1000),
           "exponent_in_nodes_at_5120_triangles": exponent("nodes", "triangles", 5120)}
    folder = Path("results/bench")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "mesh_obstacle.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
