"""Rate search: the smallest stream of a codec whose worst joint error stays within a bound (:mod:`.search`)."""

from mocapbench.ratesearch.search import KNOBS, Knob, SearchResult, ratio, search, with_config

__all__ = ["KNOBS", "Knob", "SearchResult", "ratio", "search", "with_config"]
