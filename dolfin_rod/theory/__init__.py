"""The paper's laws in UFL (Sections 2-4), shared by the rod and the torsion model:
rotations, kinematics, energy, natural state, dissipation, evolution, balance, constraints."""
