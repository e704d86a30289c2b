"""Unit tests of cosserat_fem/rod/, one file a module."""
