"""The frequency-count search grows from the cheap end and ends where the search from the safe end ends."""

from __future__ import annotations

import dataclasses

import pytest

from mocapbench.ratesearch.search import KNOBS, Knob, SearchResult, _bisect


def _run(knob: Knob, answer: int, bound: float = 1.0):
    """Drive the search with a clip whose error is under ``bound`` from K = ``answer`` on and whose stream grows
    with K; returns (the chosen K, the K tried in order)."""
    tried = []
    steps = _bisect(knob, {}, bound, 12)
    request = next(steps)
    while True:
        k = request[0][knob.field]
        tried.append(k)
        error = 0.5 if k >= answer else 2.0 + 1.0 / (k + 1)
        result = SearchResult(None, b"x" * (k + 1), {knob.field: k}, error, error, error <= bound, False, 0)
        try:
            request = steps.send(result)
        except StopIteration as done:
            return done.value.settings[knob.field], tried, done.value


@pytest.mark.parametrize("answer", [0, 1, 2, 3, 7, 11, 33, 64])
def test_growing_chooses_what_the_safe_end_first_chose_and_never_tries_above_twice_the_answer(answer):
    grow = KNOBS["fourier-mlp-int"]
    assert grow.grow and grow.low == 0 and grow.high == 64
    old = dataclasses.replace(grow, grow=False)
    chosen, tried, result = _run(grow, answer)
    chosen_old, tried_old, _ = _run(old, answer)
    assert chosen == chosen_old == answer and result.met and result.tries == len(tried)
    assert max(tried) <= max(1, 2 * answer) and tried[0] == 0
    if 0 < answer < 32:
        assert 64 in tried_old and 64 not in tried  # the largest network of the range is never trained


def test_growing_past_the_range_keeps_the_closest_try():
    chosen, tried, result = _run(KNOBS["fourier-mlp-int"], answer=100)
    assert tried == [0, 1, 2, 4, 8, 16, 32, 64] and chosen == 64 and not result.met
