"""Unit tests of cosserat_fem/analysis/, one file a module."""
