"""Benchmarks: scripts that print figures and ratios, never pass/fail (``python -m bench.NAME`` or
``python bench/NAME.py`` from the repository root)."""
