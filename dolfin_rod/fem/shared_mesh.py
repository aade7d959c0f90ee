"""Meshes and function spaces shared by the models of one layout in a process (issue 30,
target 1: set-up time).

A rod model's mesh depends on its layout (rods' lengths and cell counts) only, and its
spaces on the mesh and the model's kind: a second model of the same layout takes the mesh
(``mesh``) and the spaces (``space``, by role: "blocks", "reference strains", a stepper's
mixed space, ...) of the first instead of building them again (a mesh and ten spaces:
about 2 ms of a second model and its stepper's 13 ms, docs/performance.md).  Every model
keeps Functions and Constants of its own; DOLFINx changes no mesh or space after making
it, so sharing them changes no number.  The last ``SHARED`` meshes are kept, each with
its spaces.  Under MPI the ranks agree on every hit (one Allreduce): meshes and spaces
are made collectively, and a rank that built models alone (on another communicator) may
have dropped an entry the others kept.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Callable, Hashable

from mpi4py import MPI

SHARED = 8
_MESHES: OrderedDict = OrderedDict()     # (key, comm size) -> (mesh, {role: space})


def _agreed(comm, hit: bool) -> bool:
    """Whether every rank of ``comm`` has the hit."""
    return comm.allreduce(hit, op=MPI.LAND) if comm.size > 1 else hit


def mesh(key: Hashable, comm, make: Callable):
    """The mesh of ``key`` (e.g. a rod layout) on ``comm``: the one kept from an earlier
    call with an equal key and a congruent communicator, else ``make()`` (kept)."""
    entry = _MESHES.get((key, comm.size))
    hit = entry is not None and MPI.Comm.Compare(entry[0].comm, comm) in (MPI.IDENT,
                                                                         MPI.CONGRUENT)
    if not _agreed(comm, hit):
        entry = (make(), {})
        _MESHES[(key, comm.size)] = entry
        while len(_MESHES) > SHARED:
            _MESHES.popitem(last=False)
    _MESHES.move_to_end((key, comm.size))
    return entry[0]


def space(mesh, role: Hashable, make: Callable):
    """What ``make()`` makes on ``mesh`` for ``role`` (a space, or spaces with maps
    between them): made once for a kept mesh (mesh()), every time for any other."""
    roles = next((own for kept, own in _MESHES.values() if kept is mesh), None)
    if not _agreed(mesh.comm, roles is not None and role in roles):
        made = make()
        if roles is not None:
            roles[role] = made
        return made
    return roles[role]
