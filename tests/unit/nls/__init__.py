"""Unit tests of cosserat_fem/nls/, one file a module."""
