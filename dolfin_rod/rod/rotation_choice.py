"""The rod's rotation unknowns: quaternions or rotation vectors (rod/discretisation.py),
chosen for RodModel and scenes alike."""

from __future__ import annotations


ROTATIONS = ("auto", "quaternion", "rotation_vector")


def rotation_vector_obstacle(dynamic: bool, variant: str, constraint,
                             rotary_inertia: bool = True, rate_dependent: bool = False,
                             rotation_held: bool = True) -> str | None:
    """Why rotation vectors (rod/rotation_vector.py) do not fit a rod, or None.  They
    need the local variant (the uniform one's real-space natural strains take the
    blocked assembly) and no constraint (its multipliers make a saddle point); a dynamic
    rod needs rotary inertia section_inertia > 0 (the integrator's start solves the mass
    matrices for the accelerations); a quasi-static rod needs no rate-dependent force
    (``rate_dependent``: Kelvin-Voigt viscosity M, N or drag; its positions and rotations
    are then algebraic unknowns) and an end that holds its rotation (``rotation_held``:
    else a free spin is a null mode of the unpivoted banded LU)."""
    if variant != "local":
        return "the uniform variant (use the local one)"
    if constraint is not None:
        return f"a constrained rod ({constraint})"
    if dynamic and not rotary_inertia:
        return "a dynamic rod without rotary inertia section_inertia > 0"
    if not dynamic and rate_dependent:
        return "a quasi-static rod with Kelvin-Voigt viscosity (M, N) or drag"
    if not dynamic and not rotation_held:
        return "a quasi-static rod whose rotation no end holds (clamped or end_rotation)"
    return None


def choose_rotations(rotations: str, obstacle: str | None, lie_integrator: bool = True,
                     rotation_jumps: bool = False) -> str:
    """The rod's rotation unknowns (rod/discretisation.py): "auto" takes rotation vectors
    where nothing stands against them (``obstacle``: rotation_vector_obstacle), the
    integrator advances them (``lie_integrator``: generalized-alpha on the rotation
    group for a dynamic rod, any scheme of TimeStepper for a quasi-static one; not PETSc
    TS) and no prescribed end rotation jumps (``rotation_jumps``: a step's nodal
    increment must stay below a quarter turn, RotationVectorChart.check_increment);
    quaternions otherwise.  An explicit choice is checked (ValueError)."""
    if rotations not in ROTATIONS:
        raise ValueError(f"rotations must be one of {ROTATIONS}, got {rotations!r}")
    if rotations == "auto":
        return "rotation_vector" if obstacle is None and lie_integrator \
            and not rotation_jumps else "quaternion"
    if rotations == "rotation_vector" and (obstacle or not lie_integrator):
        why = obstacle or ("PETSc TS or a first-order scheme of a dynamic rod (rotation "
                           "vectors: generalized_alpha[:rho_inf] of TimeStepper)")
        raise ValueError(f"rotations = 'rotation_vector' does not apply to {why}; use "
                         "'quaternion'")
    return rotations



def rotations_reason(rotations: str, obstacle: str | None, lie_integrator: bool = True,
                     rotation_jumps: bool = False) -> str:
    """The rotation unknowns choose_rotations picks, and why, in plain words (for
    ``dolfin-rod check``)."""
    chosen = choose_rotations(rotations, obstacle, lie_integrator, rotation_jumps)
    if chosen == "rotation_vector":
        what = ("rotation vectors (a rotation increment of 3 unknowns per node: no "
                "unit-length multiplier, so linear systems without a saddle point)")
    else:
        what = ("quaternions (4 unknowns per node kept at unit length by a multiplier: a "
                "saddle-point system, but every time scheme applies)")
    if rotations != "auto":
        return f"{what}; geometry.rotations = {rotations!r} in the scene"
    if chosen == "rotation_vector":
        return (f"{what}; chosen by geometry.rotations = 'auto' since nothing here needs "
                "quaternions, and rotation vectors are the fewer, cheaper unknowns")
    why = obstacle or ("a prescribed end rotation jumps (a step would turn a node by more "
                       "than a quarter turn)" if rotation_jumps else
                       "the integrator does not step rotation vectors (PETSc TS, or a "
                       "first-order time.scheme of a dynamic rod; generalized_alpha does)")
    return f"{what}; chosen by geometry.rotations = 'auto' since rotation vectors do not fit here: {why}"
