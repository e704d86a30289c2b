"""Unit tests of cosserat_fem/timestepping/, one file a module."""
