"""Experiments: the evaluation row, Hydra sweeps, aggregation and reports."""
