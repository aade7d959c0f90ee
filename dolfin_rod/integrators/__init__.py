"""Time integration of a model's ``SemiDiscreteProblem``: per-step schemes (schemes.py,
stepper.py), generalized-alpha on the rotation group (lie_alpha.py), PETSc TS (ts.py) and
the step rules they share (step_control.py).  The integrator of a problem is chosen in
one place, choice.py: ``choose_integrator`` (a scene's run, scenes/builders.py) and the
one-liner ``TimeStepper(problem)`` that delegates to it."""
