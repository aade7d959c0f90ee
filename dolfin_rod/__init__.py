"""dolfin_rod: special Cosserat rods with evolving natural configurations in FEniCSx."""

__version__ = "0.1.0"
