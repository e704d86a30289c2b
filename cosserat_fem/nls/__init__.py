"""Nonlinear solvers: the Newton loop (C core through native_newton), PETSc SNES, and the choice
between them."""
