"""Finite-element machinery (issue 24 layout): multipoint.py, linear multi-point
constraints on an assembled system."""
