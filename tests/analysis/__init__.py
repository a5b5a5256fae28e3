"""Tests of tanksynth.analysis (a package, so that test modules may share names with tests/design)."""
