"""Obstacles as numbers (issue 26; docs/contact.md): their shapes and data, the signed
distance to their surfaces (one formula for numpy and, through ``Ops``, for UFL:
rod/contact.py's forms), the sweep test of a step, the gaps of points and the error of a
rod that starts cutting into one.  Numpy only, no DOLFINx: ``dolfin-rod check`` refuses a
rod that starts inside an obstacle with the message run gives (scenes/contact.py)."""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .segments import chord_reaches_edge
from .triangle_mesh import Surface, placed_surface

SHAPES = ("plane", "sphere", "cylinder", "mesh")
CONTACT_MODES = ("auto", "nodes", "segments")   # where an obstacle's barrier acts
SEGMENT_SHAPES = ("sphere", "cylinder", "mesh")  # ... on segments (a mesh: its sharp
                                                 # edges): obstacle_segments.py
SWEEP_DEPTH = 48          # halvings of a segment's sweep in a step (sweep_entry)


class InitialOverlap(ValueError):
    """The rod's initial state meets an obstacle (``obstacle``: its index)."""

    def __init__(self, reason: str, obstacle: int):
        super().__init__(reason)
        self.obstacle = obstacle

    @classmethod
    def at(cls, where: str, s: float, g: float, k: int, gap: float,
           shape: str, rod: str | None = None) -> "InitialOverlap":
        """The overlap of ``where`` ("centre line", "segment") at s (of the rod named
        ``rod`` of a system: its own arc length), gap g <= 0 to obstacles[k] of
        ``shape``, with where the rod may start instead: a rod just
        touching (|g| at most a millionth of the gap: round-off of a rod laid on a floor
        at its radius) starts where the barrier is infinite; a rod behind a mesh may see
        its triangles turned the wrong way (an open bowl given clockwise from inside)."""
        place = (f"start it off the surface by a gap in (0, {gap:.3g}] (contact.gap; "
                 "the barrier holds the rod there) or farther")
        if shape == "mesh":
            place += (f"; if the rod is on the side it should stay on, the triangles of "
                      f"obstacles[{k}] face the other way: give them counter-clockwise "
                      f"seen from the rod's side")
        what = f"the rod's {where}" if rod is None else f"the {where} of rod {rod!r}"
        if -g <= 1e-6 * gap:
            return cls(f"{what} at s = {s:.4g} touches obstacles[{k}] at t = 0 "
                       f"(gap 0 between the surfaces, where the barrier is infinite): "
                       f"{place}", k)
        return cls(f"{what} at s = {s:.4g} is {-g:.3g} closer to obstacles[{k}] "
                   f"than the rod's radius at t = 0 (it cuts into the obstacle): move the "
                   f"obstacle or the rod; {place}", k)


@dataclass
class Obstacle:
    """A rigid obstacle, in the keys of a scene's [[obstacles]]: ``shape`` "plane" (the
    half-space behind ``point`` against the outward ``normal``), "sphere" (``radius``
    around ``centre``) or "cylinder" (``radius``, ``length`` along ``axis`` through its
    ``centre``) or "mesh" (a triangle surface: ``file``, an STL or OBJ file, or
    ``vertices`` and ``triangles``, placed by x = centre + R(rotation) scale v, rotation a
    rotation vector; triangle_mesh.py); ``friction`` the Coulomb coefficient mu >= 0, or
    ``directional_friction`` (forward, backward, lateral): coefficients relative to the
    rod's axis (PyElastica's AnisotropicFrictionalPlane; rod/contact.py), ``friction``
    then their largest;
    ``contact`` where its barrier acts: "nodes" (this module), "segments" (a sphere's or
    cylinder's; a mesh's nodes and its sharp edges' segments: obstacle_segments.py) or
    "auto" (``on_segments``).
    Deprecated (this
    release only): a sphere's or cylinder's centre as ``point``, a plane's normal as
    ``axis`` (the meaning they had), with a DeprecationWarning."""

    shape: str
    point: Sequence[float] | None = None       # plane: a point of its surface
    axis: Sequence[float] | None = None        # cylinder: the axis direction
    radius: float = 0.0
    length: float = 0.0
    friction: float = 0.0
    normal: Sequence[float] | None = None      # plane: the outward normal
    centre: Sequence[float] | None = None      # sphere, cylinder: the centre; mesh: its
    file: str | None = None                    # mesh: an STL or OBJ file      # offset
    vertices: Sequence | None = None           # mesh: (n, 3) points, or from the file
    triangles: Sequence | None = None          # mesh: (m, 3) vertex indices
    rotation: Sequence[float] | None = None    # mesh: a rotation vector (radians)
    scale: float = 1.0                         # mesh: a factor on the vertices
    contact: str = "auto"                      # "nodes" | "segments" | "auto"
    directional_friction: tuple[float, float, float] | None = None  # forward, backward,
                                                                    # lateral

    def __post_init__(self):
        if self.directional_friction is not None:
            mu = tuple(float(c) for c in self.directional_friction)
            if len(mu) != 3:
                raise ValueError("Obstacle directional_friction must be (forward, backward, "
                                 f"lateral), got {self.directional_friction!r}")
            if self.friction not in (0.0, max(mu)):
                raise TypeError("Obstacle: give friction or directional_friction, not both")
            self.directional_friction, self.friction = mu, max(mu)
        old, new = ("axis", "normal") if self.shape == "plane" else ("point", "centre")
        if self.shape != "mesh" and getattr(self, old) is not None:
            if getattr(self, new) is not None:
                raise TypeError(f"Obstacle: give {new} or the deprecated {old}, not both")
            warnings.warn(f"Obstacle: a {self.shape}'s {old!r} is deprecated and goes in "
                          f"the next release: use {new} (the scene's key)",
                          DeprecationWarning, stacklevel=3)
            setattr(self, new, getattr(self, old))
            setattr(self, old, None)

    @property
    def where(self) -> Sequence[float]:
        """The plane's point or the centre (the origin if not given)."""
        where = self.point if self.shape == "plane" else self.centre
        return (0.0, 0.0, 0.0) if where is None else where

    @functools.cached_property
    def surface(self) -> Surface:
        """A mesh's checked and placed surface (MeshError naming the key at fault)."""
        return placed_surface(self.file, self.vertices, self.triangles, self.centre,
                              self.rotation, self.scale)

    @property
    def direction(self) -> Sequence[float]:
        """The plane's normal or the cylinder's axis (e_3 if not given)."""
        direction = self.normal if self.shape == "plane" else self.axis
        return (0.0, 0.0, 1.0) if direction is None else direction

def check_contact_mode(name: str, ob: Obstacle) -> None:
    """ValueError naming ``name``.contact if the obstacle's contact mode is not one of
    CONTACT_MODES, or "segments" on a shape it does not apply to (a plane)."""
    if ob.contact not in CONTACT_MODES:
        raise ValueError(f"{name}.contact must be one of {', '.join(CONTACT_MODES)}, got "
                         f"{ob.contact!r}")
    if ob.contact == "segments" and ob.shape not in SEGMENT_SHAPES:
        raise ValueError(f"{name}.contact = 'segments' applies to a sphere, a cylinder or "
                         f"a mesh, not a {ob.shape} (its contact acts on the nodes: "
                         "'nodes' or 'auto')")



class Ops:
    """The operations of the signed distance: numpy's (NP_OPS) or UFL's (contact.UFL_OPS)."""

    def __init__(self, dot, sqrt, max, where, le, lt, scale):
        self.dot, self.sqrt, self.max, self.where = dot, sqrt, max, where
        self.le, self.lt, self.scale = le, lt, scale


NP_OPS = Ops(lambda a, b: np.sum(a * b, axis=-1), np.sqrt, np.maximum, np.where,
             np.less_equal, np.less, lambda z, a: z[..., None] * a)


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


class Pose:
    """An obstacle's shape and data (unit axis) as numbers, or each made by ``constant``
    (rod/contact.py: fem.Constants on the rod's mesh, so that forms of the same shapes
    share their kernels: form_cache)."""

    def __init__(self, ob: Obstacle, constant: Callable | None = None):
        values = {"point": np.asarray(ob.where, float), "axis": unit(ob.direction)
                  if np.linalg.norm(ob.direction) > 0 else np.array([0.0, 0.0, 1.0]),
                  "radius": float(ob.radius), "length": float(ob.length),
                  "friction": float(ob.friction)}
        self.shape = ob.shape
        for name, value in values.items():
            setattr(self, name, value if constant is None else constant(value))


class MeshPose:
    """A mesh obstacle's surface and friction as numbers (rod/contact.MeshFields: its
    nodes' closest features as fields of the rod's mesh); ``tree``: its distances
    searched by a cKDTree (False: compared all, while few: triangle_mesh.Surface.
    candidates)."""

    shape = "mesh"

    def __init__(self, ob: Obstacle, tree: bool = True):
        self.surface, self.tree = ob.surface, tree
        self.friction = float(ob.friction)

    def distance(self, p, ops: Ops):
        return self.surface.signed_distance(p, self.tree)


def make_pose(ob: Obstacle, tree: bool = True) -> Pose | MeshPose:
    """The obstacle's Pose (a mesh's MeshPose, ``tree`` as there) as numbers."""
    return MeshPose(ob, tree) if ob.shape == "mesh" else Pose(ob)


def signed_distance(pose: Pose | MeshPose, p, ops: Ops = NP_OPS):
    """Distance of the point p (numpy (n, 3), or a UFL 3-vector with contact.UFL_OPS) to
    the obstacle's surface, negative inside."""
    if pose.shape == "mesh":
        return pose.distance(p, ops)
    d, a = p - pose.point, pose.axis
    if pose.shape == "plane":
        return ops.dot(d, a)
    if pose.shape == "sphere":
        return ops.sqrt(ops.dot(d, d)) - pose.radius
    z = ops.dot(d, a)                                   # cylinder: along the axis
    radial = d - ops.scale(z, a)
    e_r = ops.sqrt(ops.dot(radial, radial)) - pose.radius
    e_z = abs(z) - pose.length / 2
    outside = ops.max(e_r, 0.0) ** 2 + ops.max(e_z, 0.0) ** 2
    inside = ops.le(ops.max(e_r, e_z), 0.0)             # sqrt(0) has no derivative
    return ops.where(inside, ops.max(e_r, e_z), ops.sqrt(ops.where(inside, 1.0, outside)))


def gaps(poses: Sequence[Pose | MeshPose], points: np.ndarray, radius: float) -> np.ndarray:
    """(points, obstacles) gaps d - r of the points (n, 3) of a centre line of radius r."""
    return np.stack([signed_distance(pose, points) - radius for pose in poses],
                    axis=-1).reshape(len(points), -1)


def fixed_segments(ob: Obstacle, reach: float, h: float):
    """(q0 (m, 3), q1 (m, 3), radius (m,)) of the obstacle's fixed segments: a cylinder's
    axis from lid to lid, a sphere's centre twice (radius R); a mesh's convex edges that
    nodes h apart cannot hold a rod across, (h / 2) sin(phi / 2) >= reach = r + delta
    (phi the angle between the faces' normals: a chord across the edge touches it while
    its nodes are beyond the barrier's reach from both faces; radius 0)."""
    if ob.shape == "mesh":
        ends, turn = ob.surface.convex_edges()
        sharp = chord_reaches_edge(h, turn, reach)
        return ends[sharp, 0], ends[sharp, 1], np.zeros(int(sharp.sum()))
    centre = np.asarray(ob.where, float)
    half = 0.5 * ob.length * unit(ob.direction) if ob.shape == "cylinder" else 0.0 * centre
    return (centre - half)[None], (centre + half)[None], np.array([ob.radius])


def sweep_entry(poses: Sequence[Pose | MeshPose], A0: np.ndarray, A1: np.ndarray,
                B0: np.ndarray | None = None, B1: np.ndarray | None = None):
    """(segment, obstacle) of a segment whose straight sweep enters an obstacle (numpy
    poses: signed distance d <= 0 somewhere), or None: segment i runs from A(tau) to
    B(tau) with A(tau) = A0 + tau (A1 - A0) (each (n, 3); B as A if not given: the
    nodes' paths), its points p(sigma, tau) = A + sigma (B - A) for sigma, tau in
    [0, 1].  d is 1-Lipschitz in the point and |dp/dsigma| <= L_s = max(|B0 - A0|,
    |B1 - A1|) (|B - A| is convex in tau), |dp/dtau| <= L_t = max(|A1 - A0|, |B1 - B0|),
    so on a rectangle of the (sigma, tau) square d stays > 0 if d at its centre exceeds
    (L_s dsigma + L_t dtau) / 2; other rectangles are halved along their longer side
    (in those bounds), SWEEP_DEPTH times at most (still open after them: counted as an
    entry).  (The body, not the body thickened by the rod's radius: a rod sliding on a
    curved obstacle at a small gap has chords that cut into the gap, not into the
    body.)"""
    B0, B1 = (A0, A1) if B0 is None else (B0, B1)
    L_s = np.maximum(np.linalg.norm(B0 - A0, axis=1), np.linalg.norm(B1 - A1, axis=1))
    L_t = np.maximum(np.linalg.norm(A1 - A0, axis=1), np.linalg.norm(B1 - B0, axis=1))
    for k, pose in enumerate(poses):
        idx = np.arange(len(A0))
        s0, s1, t0, t1 = (np.full(len(idx), v) for v in (0.0, 1.0, 0.0, 1.0))
        for _ in range(SWEEP_DEPTH):
            sc, tc = (0.5 * (s0 + s1))[:, None], (0.5 * (t0 + t1))[:, None]
            A = A0[idx] + tc * (A1 - A0)[idx]
            d = signed_distance(pose, A + sc * (B0[idx] + tc * (B1 - B0)[idx] - A))
            if (d <= 0).any():
                return int(idx[d <= 0][0]), k
            ds, dt = L_s[idx] * (s1 - s0), L_t[idx] * (t1 - t0)
            open_ = d <= 0.5 * (ds + dt)
            if not open_.any():
                break
            idx, s0, s1, t0, t1, ds, dt = (v[open_] for v in (idx, s0, s1, t0, t1, ds, dt))
            along_s = ds >= dt
            sm, tm = np.where(along_s, 0.5 * (s0 + s1), s1), np.where(along_s, t1,
                                                                   0.5 * (t0 + t1))
            # the first halves [s0, sm] x [t0, tm] and the second ones beyond sm (or tm)
            idx, s0, s1, t0, t1 = (np.concatenate(v) for v in (
                (idx, idx), (s0, np.where(along_s, sm, s0)), (sm, s1),
                (t0, np.where(along_s, t0, tm)), (tm, t1)))
        else:
            return int(idx[0]), k
    return None

