"""Unit tests of benchmarks/, one file a module."""
