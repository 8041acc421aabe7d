"""Hydra only instantiates sweepers defined under the ``hydra_plugins`` namespace: this is the benchmark's
sweeper (:class:`mocapbench.experiments.sweeper.RdSweeper`) registered there; the code lives in mocapbench."""

from mocapbench.experiments.sweeper import RdSweeper


class MocapbenchSweeper(RdSweeper):
    """:class:`mocapbench.experiments.sweeper.RdSweeper` under the name Hydra's plugin check accepts."""


__all__ = ["MocapbenchSweeper"]
