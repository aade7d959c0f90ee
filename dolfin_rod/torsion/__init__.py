"""Section 5: the isolated-torsion model (model.py), its closed forms, the homogeneous ODE
(eqs. twist, nattwist) and explicit Euler's stability limit."""
