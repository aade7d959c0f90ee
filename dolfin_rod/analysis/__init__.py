"""Analyses of a rod's state (issue 27): the stability of a quasi-static equilibrium
(stability.py)."""
