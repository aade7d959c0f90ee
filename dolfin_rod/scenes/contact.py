"""The contact keys of a rod scene ([contact], [[obstacles]]; docs/contact.md): their
rules across keys and the obstacles and contact law they describe (rod/contact.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .scene import Scene
from .values import largest_friction

# per shape the pose keys it needs and those it may have (every other one is an error)
POSE_KEYS = {"plane": ("point", "normal"), "sphere": ("centre", "radius"),
             "cylinder": ("centre", "axis", "radius", "length"), "mesh": ()}
OPTIONAL_KEYS = {"mesh": ("centre", "file", "vertices", "triangles", "rotation", "scale")}
ALL_POSE_KEYS = ("point", "normal", "centre", "axis", "radius", "length", "file",
                 "vertices", "triangles", "rotation", "scale")
DIRECTIONS = ("normal", "axis")
SEGMENT_SHAPES = ("sphere", "cylinder", "mesh")     # contact = "segments" (rod/contact.py's;
                                                    # no DOLFINx for `dolfin-rod check`)
FEW_SEGMENTS = 400          # the start's pair check compares every pair (no scipy import)


def check_contact_keys(scene: Scene, rotations: str) -> None:
    """[[obstacles]] need contact.radius; [contact] needs obstacles; each obstacle has the
    pose keys of its shape; gap < radius; friction needs a dynamic rod (segment friction
    also its kind of contact; on an obstacle that acts on the segments, the rod's
    ``rotations`` (rules.rod_rotations) rotation vectors)."""
    err, contact, obstacles = scene.error, scene["contact"], scene["obstacles"]
    given = scene.given["contact"]
    if not touching(scene):
        if given:
            raise err(f"contact.{sorted(given)[0]}", "applies to rods with [[obstacles]], "
                                                     "contact.self or contact.between_rods")
        return
    if contact["between_rods"] and not (scene.rods or scene.in_system):
        raise err("contact.between_rods", "applies to the rods of a [[rods]] system; this "
                                          "scene has one rod (a rod split at its corners "
                                          "too): its own segments repel with contact.self")
    if contact["radius"] is None:
        contact["radius"] = section_radius(scene)
    if contact["radius"] is None:
        raise err("contact.radius", "missing: contact needs the rod's radius (or a "
                                    "circle or tube [section])")
    if contact["gap"] is not None and contact["gap"] >= contact["radius"]:
        raise err("contact.gap", f"must be < contact.radius = {contact['radius']:g} (the "
                                 f"barrier acts within the gap), got {contact['gap']:g}")
    for k, ob in enumerate(obstacles):
        name, needed = f"obstacles[{k}]", POSE_KEYS[ob["shape"]]
        allowed = needed + OPTIONAL_KEYS.get(ob["shape"], ())
        for key in ALL_POSE_KEYS:
            if key in needed and ob[key] is None:
                raise err(f"{name}.{key}", f"missing: a {ob['shape']} needs "
                                           f"{', '.join(needed)}")
            if key not in allowed and ob[key] is not None:
                raise err(f"{name}.{key}", f"does not apply to a {ob['shape']} (its keys: "
                                           f"{', '.join(allowed)}, friction)")
        if ob["shape"] == "mesh":
            _check_mesh(scene, k)
        for key in DIRECTIONS:
            if ob[key] is not None and not np.linalg.norm(ob[key]) > 0:
                raise err(f"{name}.{key}", "must not be the zero vector")
        mu = largest_friction(ob["friction"])
        if mu > 0 and not scene["material"]["dynamic"]:
            raise err(f"{name}.friction", "friction depends on the velocity: it needs a "
                                          "dynamic rod (material.density > 0)")
        _check_segments(scene, k)
        if mu > 0 and acts_on_segments(scene, k)[0]:
            if rotations != "rotation_vector":
                raise err(f"{name}.friction", "this obstacle acts on the segments (a "
                                              "sphere or cylinder thinner than the cells "
                                              "can hold, or a mesh's sharp edges; "
                                              "docs/contact.md): their friction needs "
                                              "rotation-vector unknowns "
                                              f"(geometry.rotations), got {rotations!r}")
    for key, pairs in (("self_friction", "self"), ("between_rods_friction", "between_rods")):
        if contact[key] > 0 and contact["pair_curve"] == "smooth":
            raise err(f"contact.{key}", "friction between segments needs "
                                        "contact.pair_curve = 'segments'")
        if contact[key] > 0 and not contact[pairs]:
            raise err(f"contact.{key}", f"applies to segments in contact: set "
                                        f"contact.{pairs} = true")
        if contact[key] > 0 and not scene["material"]["dynamic"]:
            raise err(f"contact.{key}", "friction depends on the velocity: it needs a "
                                        "dynamic rod (material.density > 0)")


def check_initial_contact(scene: Scene, start) -> None:
    """Contact at t = 0 on the rods' centre lines ``start`` (builders.StartLines, placed
    in numpy), the model's own checks before any model: self-contact whose neighbour
    exclusion covers a rod (contact.radius), a node within its radius of an obstacle or
    a cell within reach of a thin one (obstacles[k]), two segments' capsules overlapping
    (contact.self or contact.between_rods).  A start settled in equilibrium first
    (``start.settled``) is left to run."""
    c = scene["contact"]
    radius = c["radius"]
    gap = c["gap"] or radius / 10
    h = longest_cell(start)
    if c["self"]:
        from ..rod.segments import exclusion_problem
        lengths: dict = {}              # each rod's length (a kinked rod: its pieces')
        for line in start.lines:
            lengths[line.rod] = lengths.get(line.rod, 0.0) + line.length
        problem = exclusion_problem(radius, gap, h, min(lengths.values()))
        if problem:
            raise scene.error("contact.radius", problem)
    if start.settled:
        return
    _check_obstacle_overlap(scene, start.lines, radius, gap)
    cells = StartSegments(start)
    _check_segment_obstacles(scene, cells, radius, gap, h)
    if segment_pairs(scene):
        _check_pair_overlap(scene, start, cells, radius, gap, h)


class StartSegments:
    """The cells of the rods at t = 0 (builders.StartLines) as segments, the pieces laid
    on one parameter line as the model's layout lays them (a gap of the longest between
    them: layout.RodLayout.starts): their nodes' positions P, the segments' ``ends``
    (global nodes), ``piece``, parameter ``mid_s`` and own arc length ``own_s``; the
    parameter ``a`` where each piece starts; ``deviation``: how far each segment's C^1
    curve (smooth_pairs.Stencils, the model's curves) may lie from its chord."""

    def __init__(self, start):
        from ..rod.smooth_pairs import Stencils
        lines = start.lines
        spacing = max(line.length for line in lines)
        self.a = np.concatenate([[0.0], np.cumsum([line.length + spacing
                                                   for line in lines])[:-1]])
        nodes = np.concatenate([[0], np.cumsum([len(line.s) for line in lines])])
        self.P = np.vstack([line.points for line in lines])
        self.ends = np.vstack([nodes[k] + np.column_stack([np.arange(len(line.s) - 1),
                                                           np.arange(1, len(line.s))])
                               for k, line in enumerate(lines)])
        self.piece = np.concatenate([np.full(len(line.s) - 1, k)
                                     for k, line in enumerate(lines)])
        self.own_s = np.concatenate([0.5 * (line.s[1:] + line.s[:-1]) for line in lines])
        self.mid_s = self.a[self.piece] + self.own_s - np.concatenate(
            [np.full(len(line.s) - 1, line.s[0]) for line in lines])
        self.deviation = Stencils(self.ends, self.piece).deviation(self.P)
        self.rods = [line.rod for line in lines]

    def name(self, m: int) -> str:
        """Segment m as the model names it (pair_contact.segment_name), by its rod's own
        arc length."""
        rod = self.rods[self.piece[m]]
        return f"{'the rod' if rod is None else f'rod {rod}'} at s = {self.own_s[m]:.4g}"


def longest_cell(start) -> float:
    """The longest cell of the rods (their pieces: the model's layout) at t = 0."""
    return max(line.length / (len(line.s) - 1) for line in start.lines)


def _check_obstacle_overlap(scene: Scene, lines: list, radius: float, gap: float) -> None:
    """A rod whose nodes start within its radius of an obstacle (rod/obstacle_shapes.py:
    the gaps of the model's check at t = 0): the error naming obstacles[k] run gives."""
    from ..rod.obstacle_shapes import InitialOverlap, gaps, make_pose
    if not scene["obstacles"]:
        return
    poses = [make_pose(obstacle(scene, ob), tree=False)      # (no scipy import)
             for ob in scene["obstacles"]]
    nearest = []
    for line in lines:
        g = gaps(poses, line.points, radius)
        i, k = np.unravel_index(np.argmin(g), g.shape)
        nearest.append((float(g[i, k]), float(line.s[i]), int(k), line.rod))
    g, s, k, rod = min(nearest, key=lambda near: near[0])
    if g <= 0:
        raise scene.error(f"obstacles[{k}]", str(InitialOverlap.at(
            "centre line", s, g, k, gap, scene["obstacles"][k]["shape"], rod)))


def _check_pair_overlap(scene: Scene, start, cells: StartSegments, radius: float,
                        gap: float, h: float) -> None:
    """Two segments of the rods that make a pair (pair_contact.SegmentContact.allowed:
    of one rod (any of its pieces: a rod split at its kinks) farther apart along it than
    the exclusion with contact.self, of two with contact.between_rods, not neighbours
    through a joint) whose capsules overlap at
    t = 0: the error naming contact.self or contact.between_rods run gives.  On smooth
    curves (contact.pair_curve = "smooth") the curves' distance is at most the chords'
    plus the two deviations: a pair that overlaps by that bound overlaps (exact for
    straight cells; a closer call is left to the model)."""
    from ..rod.segments import PairOverlap, closest_points, exclusion, joint_distances, \
        near_pairs
    c, lines, P, ends = scene["contact"], start.lines, cells.P, cells.ends
    smooth = c["pair_curve"] == "smooth"
    reach, excluded = 2 * radius + gap, exclusion(radius, gap, h)
    pairs = near_pairs(P[ends[:, 0]], P[ends[:, 1]], cells.mid_s,
                       reach + 2 * cells.deviation.max() * smooth, 0.0,
                       tree=len(ends) > FEW_SEGMENTS)
    i, j = pairs[:, 0], pairs[:, 1]
    rod = np.array([cells.rods.index(name) for name in cells.rods])[cells.piece]
    same = rod[i] == rod[j]
    keep = (same & c["self"] & (np.abs(cells.own_s[i] - cells.own_s[j]) >= excluded)) | \
        (~same & c["between_rods"])
    joints = [tuple(cells.a[p] + node * lines[p].length / (len(lines[p].s) - 1)
                    for p, node in ((p, m), (q, n))) for p, m, q, n in start.joints]
    for near in joint_distances(cells.mid_s, joints):      # neighbours through a joint
        keep &= near[i] + near[j] >= excluded
    i, j = i[keep], j[keep]
    X = [P[ends[i, 0]], P[ends[i, 1]], P[ends[j, 0]], P[ends[j, 1]]]
    u, v, d = closest_points(*X)
    if smooth:
        d = d + cells.deviation[i] + cells.deviation[j]
    if not len(d) or d.min() - 2 * radius > 0:
        return
    k = int(np.argmin(d))
    point = 0.5 * (X[0][k] + u[k] * (X[1][k] - X[0][k]) + X[2][k] + v[k] * (X[3][k] - X[2][k]))
    err = PairOverlap.at((cells.name(i[k]), cells.name(j[k])), point,
                         float(d[k] - 2 * radius), radius,
                         bool(same[keep][k]))
    raise scene.error(err.key, str(err))


def _check_segment_obstacles(scene: Scene, cells: StartSegments, radius: float,
                             gap: float, h: float) -> None:
    """A cell within R + r of an obstacle that acts on the segments (a thin sphere or
    cylinder, a mesh's sharp edges: segments.on_segments with the longest cell h, as the
    model decides; rod/obstacle_shapes.fixed_segments) at t = 0: the error naming
    obstacles[k] the model gives.  On smooth curves (contact.obstacle_curve = "smooth",
    the default) the curve's distance is at most the chord's plus its deviation: a cell
    that overlaps by that bound overlaps (exact for straight cells)."""
    from ..rod.obstacle_shapes import InitialOverlap, fixed_segments
    from ..rod.segments import closest_points, on_segments
    c, P, ends = scene["contact"], cells.P, cells.ends
    nearest = []
    for k, ob in enumerate(scene["obstacles"]):
        body = obstacle(scene, ob)
        turn = body.surface.convex_edges()[1] if ob["shape"] == "mesh" else ()
        if not on_segments(ob["contact"], ob["shape"], ob["radius"] or 0.0, radius + gap,
                           h, turn):
            continue
        q0, q1, R = fixed_segments(body, radius + gap, h)
        if not len(R):
            continue
        cell, q = (v.ravel() for v in np.indices((len(ends), len(R))))
        d = closest_points(P[ends[cell, 0]], P[ends[cell, 1]], q0[q], q1[q])[2]
        g = d - R[q] - radius + cells.deviation[cell] * (c["obstacle_curve"] == "smooth")
        m = int(np.argmin(g))
        nearest.append((float(g[m]), int(cell[m]), k))
    if not nearest:
        return
    g, m, k = min(nearest)
    if g <= 0:
        raise scene.error(f"obstacles[{k}]", str(InitialOverlap.at(
            "segment", cells.own_s[m], g, k, gap, scene["obstacles"][k]["shape"],
            cells.rods[cells.piece[m]])))


def _check_segments(scene: Scene, k: int) -> None:
    """contact = "segments": a sphere, a cylinder or a mesh (rod/contact.py
    check_contact_mode, with the scene's keys)."""
    ob, name = scene["obstacles"][k], f"obstacles[{k}]"
    if ob["contact"] != "segments":
        return
    if ob["shape"] not in SEGMENT_SHAPES:
        raise scene.error(f"{name}.contact", f"'segments' applies to a sphere, a "
                                             f"cylinder or a mesh, not a {ob['shape']}: "
                                             "'nodes' or 'auto'")


def _check_mesh(scene: Scene, k: int) -> None:
    """A mesh obstacle: a file or vertices and triangles, a surface (read and checked
    now: rod/triangle_mesh.py), and an integrator that evaluates one state per step."""
    from ..rod.triangle_mesh import MeshError
    err, ob, name = scene.error, scene["obstacles"][k], f"obstacles[{k}]"
    for key in ("scheme", "ts_type"):
        if key in scene.given["time"]:
            raise err(f"time.{key}", f"{name} is a mesh: it is solved by generalized-alpha "
                                     "or quasi-statically (its nodes' closest features are "
                                     "those of one state per step; docs/contact.md)")
    try:
        mesh_surface(scene, ob)
    except MeshError as bad:
        raise err(f"{name}.{bad.key}", str(bad)) from None


def obstacle(scene: Scene, ob: dict):
    """rod.contact.Obstacle of one [[obstacles]] entry (a mesh's file relative to the
    scene's folder)."""
    from ..rod.obstacle_shapes import Obstacle
    given = {key: tuple(ob[key]) for key in ("point", "normal", "centre", "axis",
                                             "rotation", "vertices", "triangles")
             if ob[key] is not None}           # the shape's keys only (checked above)
    if ob["file"] is not None:
        given["file"] = mesh_file(scene, ob)
    mu = ob["friction"]
    directional = {"directional_friction": mu} if isinstance(mu, tuple) else {
        "friction": mu}
    return Obstacle(ob["shape"], radius=ob["radius"] or 0.0, length=ob["length"] or 0.0,
                    scale=ob["scale"] or 1.0, contact=ob["contact"], **directional, **given)


def mesh_surface(scene: Scene, ob: dict):
    """A mesh obstacle's placed surface (rod/triangle_mesh.py: numpy only, so that
    `dolfin-rod check` stays cheap); MeshError naming the key at fault."""
    from ..rod.triangle_mesh import placed_surface
    return placed_surface(mesh_file(scene, ob), ob["vertices"], ob["triangles"],
                          ob["centre"], ob["rotation"], ob["scale"] or 1.0)


def mesh_file(scene: Scene, ob: dict) -> str | None:
    """A mesh obstacle's file, relative to the scene's folder (None: not given)."""
    if ob["file"] is None:
        return None
    return str((scene.folder or Path()) / ob["file"])


def contact_lines(scene: Scene, start) -> list[str]:
    """``check``'s line per obstacle: where its barrier acts, nodes or segments
    (rod/segments.on_segments with the longest cell h; a mesh's sharp edges,
    rod/obstacle_shapes.fixed_segments); then ``pair_lines`` (``start``: the rods at
    t = 0, builders.StartLines)."""
    from ..rod.segments import chord_reaches_edge
    lines = []
    for k, ob in enumerate(scene["obstacles"]):
        where = "on the nodes"
        segments, h, reach, turn = acts_on_segments(scene, k)
        if segments:
            where = "on the segments"
            if ob["shape"] == "mesh":
                edges = chord_reaches_edge(h, turn, reach).sum()
                where = f"on the nodes, its {edges} sharp edges on the segments"
        lines.append(f"contact: obstacles[{k}] ({ob['shape']}, contact = "
                     f"{ob['contact']!r}) acts {where} (longest cell h = {h:.4g})")
    return lines + pair_lines(scene, start)


def pair_lines(scene: Scene, start) -> list[str]:
    """``check``'s line for self-contact and for contact between rods (pair_contact.py):
    the capsules' radius, the barrier's gap, the pairs' curves, friction, and for
    self-contact the neighbours excluded along the rod (segments.exclusion; the longest
    cell of the rods at t = 0, ``start``: builders.StartLines)."""
    from ..rod.segments import exclusion
    c, lines = scene["contact"], []
    radius = c["radius"]
    gap = c["gap"] or radius / 10
    h = longest_cell(start)
    for key, what in (("self", "the rod's own segments"),
                      ("between_rods", "segments of different rods")):
        if not c[key]:
            continue
        said = (f"contact: {key} ({what}, capsules of radius {radius:g}, barrier gap "
                f"{gap:g}, pair_curve = {c['pair_curve']!r}")
        said += f", friction mu = {c[key + '_friction']:g})" if c[key + "_friction"] > 0 \
            else ", frictionless)"
        if key == "self":
            said += (f" excludes neighbours closer along the rod than pi (r + gap) + h = "
                     f"{exclusion(radius, gap, h):.4g} (longest cell h = {h:.4g})")
        lines.append(said)
    return lines


def acts_on_segments(scene: Scene, k: int) -> tuple[bool, float, float, tuple]:
    """Whether obstacles[k]'s barrier acts on the segments (rod/segments.on_segments:
    a sphere's or cylinder's, a mesh's sharp edges), with the longest cell h, the reach
    r + delta and a mesh's convex edges' turns."""
    from ..rod.segments import on_segments
    c, ob = scene["contact"], scene["obstacles"][k]
    reach = c["radius"] + (c["gap"] or c["radius"] / 10)
    h = max(own["geometry"]["length"] / own["geometry"]["n_cells"]
            for own in [rod.scene for rod in scene.rods] or [scene])
    turn = mesh_surface(scene, ob).convex_edges()[1] if ob["shape"] == "mesh" else ()
    return (on_segments(ob["contact"], ob["shape"], ob["radius"] or 0.0, reach, h, turn),
            h, reach, turn)


def touching(scene: Scene) -> bool:
    """Obstacles, self-contact or contact between rods."""
    c = scene["contact"]
    return bool(scene["obstacles"] or c["self"] or c["between_rods"])


def segment_pairs(scene: Scene) -> bool:
    """Self-contact or contact between rods (rod/pair_contact.py)."""
    return bool(scene["contact"]["self"] or scene["contact"]["between_rods"])


def section_radius(scene: Scene) -> float | None:
    """The radius of a circle or tube [section], else None."""
    sec = scene["section"]
    return {"circle": sec["radius"], "tube": sec["outer_radius"]}.get(sec["shape"])


def obstacles(scene: Scene) -> list:
    """rod.contact.Obstacle of each [[obstacles]] entry."""
    return [obstacle(scene, ob) for ob in scene["obstacles"]]


def contact_law(scene: Scene, params):
    """rod.contact.ContactLaw of [contact] (defaults: gap r/10, stiffness from the rod and
    dt, slip tolerance 1e-3 L / t_end), None without contact."""
    from ..rod.contact import ContactLaw, default_stiffness
    if not touching(scene):
        return None
    c, geo, tim = scene["contact"], scene["geometry"], scene["time"]
    stiffness = c["stiffness"] or default_stiffness(params.density, params.A, geo["length"],
                                                    geo["n_cells"], tim["dt"])
    return ContactLaw(c["radius"], c["gap"] or c["radius"] / 10, stiffness,
                      c["slip_tolerance"] or 1e-3 * geo["length"] / tim["t_end"],
                      self=c["self"], between_rods=c["between_rods"],
                      self_friction=c["self_friction"],
                      between_rods_friction=c["between_rods_friction"],
                      pair_curve=c["pair_curve"], obstacle_curve=c["obstacle_curve"])


def contact_solver_options(scene: Scene) -> dict:
    """Obstacles: Newton to rtol 1e-8 (the dynamic rod's 1e-4 accepts a step whose
    residual is dominated by the barrier's: docs/contact.md) unless time.rtol is given;
    friction: with a backtracking line search (the sticking law's Newton steps overshoot
    without one) and, where it fails, the l2 line search; segment pairs: without PETSc's divergence test."""
    if not touching(scene):
        return {}
    options = {} if "rtol" in scene.given["time"] else {"snes_rtol": 1e-8}
    c = scene["contact"]
    if any(largest_friction(ob["friction"]) > 0 for ob in scene["obstacles"]) \
            or c["self_friction"] > 0 \
            or c["between_rods_friction"] > 0:
        options["snes_linesearch_type"] = "bt"
        # bt stalls where a prescribed motion starts a sticking rod sliding within a step
        # (its steps shrink to 1e-4: docs/contact.md); l2 takes those steps
        options["linesearch_fallback"] = "l2"
    if segment_pairs(scene):    # a pair's barrier may raise the residual 1e4-fold on the
        options["snes_divergence_tolerance"] = -1.0     # way to its root: no divergence stop
    return options
