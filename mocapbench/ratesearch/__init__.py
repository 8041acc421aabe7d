"""Rate search: the smallest stream of a codec whose worst joint error stays within a bound (:mod:`.search`), its
source clip's forward kinematics computed once for every try (:mod:`.source`)."""

from mocapbench.ratesearch.search import KNOBS, Knob, SearchResult, ratio, search, search_many, with_config
from mocapbench.ratesearch.source import known_kinematics

__all__ = ["KNOBS", "Knob", "SearchResult", "known_kinematics", "ratio", "search", "search_many", "with_config"]
