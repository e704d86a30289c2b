"""Unit tests, one file a module: tests/unit/<subpackage>/test_<module>.py mirrors
cosserat_fem/<subpackage>/<module>.py (tests/unit/test_mirror.py holds it). A package, so that
a test file may share its basename with an integration test in tests/ (pytest names it
unit.<subpackage>.test_<module>)."""
