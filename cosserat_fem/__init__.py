"""cosserat-fem: the Cosserat rod of Cao & Tucker (2008) in FEniCSx/DOLFINx.

The physics (pure UFL) lives in :mod:`cosserat_fem.forms` (the top-level ``forms/`` folder);
this package is the machinery: scenes, spaces and boundary conditions, time integrators,
the SNES solver, outputs and the command line.
"""

__version__ = "0.1.0"
