"""Benchmarks that print figures. ``python -m bench`` runs them all; ``python -m bench NAME`` one of them.

Each module ``bench/bench_*.py`` defines ``main() -> None`` and prints its figures. Nothing here asserts on time.
"""
