"""Data files shipped with tanksynth (the built-in demo spec)."""
