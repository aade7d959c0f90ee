"""Fitting scene parameters to measured time series (docs/fitting.md): the least squares
(least_squares.py), its inputs (inputs.py) and the ``dolfin-rod fit`` command."""
