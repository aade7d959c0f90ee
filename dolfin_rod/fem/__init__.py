"""Finite-element machinery: the semi-discrete problem, assembly, nonlinear solvers, the
compiled-form cache, the interval-mesh toolkit (fe_model.py), linear multi-point
constraints on an assembled system (multipoint.py) and compat.py (every DOLFINx 0.9 /
0.11 difference)."""
