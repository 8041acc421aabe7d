"""Speed benchmarks run as modules, e.g. ``python -m mocapbench.benchmarks.io`` (never asserted in tests)."""
