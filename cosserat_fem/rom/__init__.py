"""Reduced models of the rod from POD modes (issue 28; docs/rom.md): the basis
(cosserat_fem/rom/basis.py, offline) and the Galerkin-reduced solve in the time loop
(cosserat_fem/rom/galerkin.py, online)."""
