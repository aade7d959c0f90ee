"""Analyses of a rod's state (issue 27, docs/stability.md):

    stability.py     the stability of a quasi-static equilibrium (the tangent's inertia)
    branches.py      switching onto the stable branch at a bifurcation
    continuation.py  arc-length continuation through limit points
    buckling.py      linearised critical load factors and modes (dolfin-rod buckle)
    vibration.py     natural frequencies and modes about the current state (dolfin-rod modes)
    eigen.py         the one SLEPc eigen-solve they share
"""
