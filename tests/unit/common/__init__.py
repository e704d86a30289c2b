"""Unit tests of cosserat_fem/common/, one file a module."""
