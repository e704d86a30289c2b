"""Unit tests of cosserat_fem/scene/, one file a module."""
