"""Unit tests of cosserat_fem/io/, one file a module."""
