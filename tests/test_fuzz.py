"""Fuzzing the decoders: the saved findings (default run) and a bounded campaign (``pytest -m fuzz``).

The long campaign is one command: ``python -m mocapbench.fuzz --per-codec 8000`` (see :mod:`mocapbench.fuzz`).
"""

from __future__ import annotations

import os
import time

import pytest

from mocapbench.codecs import CODECS, UNAVAILABLE, BitstreamError, DecodeLimits, create
from mocapbench.fuzz import REGRESSION_DIR, mutations, restamp, run_campaign, seed_streams
from mocapbench.codecs.container import read_header

REGRESSIONS = sorted(REGRESSION_DIR.glob("*.mcb"))
# Streams per codec and files per surface in the bounded run (CI); the long run is `python -m mocapbench.fuzz`.
PER_CODEC = int(os.environ.get("MOCAPBENCH_FUZZ_PER_CODEC", "400"))
PER_SURFACE = int(os.environ.get("MOCAPBENCH_FUZZ_PER_SURFACE", "200"))


def test_every_saved_finding_is_a_bitstream_error_within_seconds():
    """Each file of tests/fuzz_regressions (the issue's reproducers and every campaign finding since)."""
    assert REGRESSIONS, f"no regression inputs in {REGRESSION_DIR}"
    for path in REGRESSIONS:
        data = path.read_bytes()
        name = path.name.rsplit("-", 1)[0]
        if name in UNAVAILABLE and name not in CODECS:  # e.g. fourier-mlp-* without torch (the [neural] extra)
            continue
        started = time.perf_counter()
        with pytest.raises(BitstreamError):
            create(name, **CODECS[name].smoke_params).decode(data)
        assert time.perf_counter() - started < 5.0, path.name


def test_mutations_keep_the_container_valid_and_are_deterministic():
    stream = seed_streams(["quant-delta-zstd"])["quant-delta-zstd"][0]
    first = list(mutations(stream, 40, seed=7))
    assert first == list(mutations(stream, 40, seed=7))
    assert {kind for kind, _ in first} == {"header", "field", "zstd", "random"}
    reached = 0
    for kind, data in first:
        assert data != stream
        if kind in ("field", "zstd"):
            read_header(data)  # CRC and length recomputed: the payload parser is reached
            reached += 1
    assert reached == 20
    assert restamp(stream) == stream


@pytest.mark.fuzz
def test_bounded_fuzz_campaign_has_no_findings():
    from mocapbench.fuzz.surfaces import SURFACES

    result = run_campaign(sorted(CODECS), PER_CODEC, seed=1, workers=2, timeout_s=5.0, per_surface=PER_SURFACE)
    print(result.table())
    print(result.surface_table())
    files = sum(sum(result.counts[surface].values()) for surface in SURFACES)
    assert result.total - files == PER_CODEC * len(CODECS)
    assert files >= PER_SURFACE * 4  # FBX needs ufbx; every other surface always runs
    described = [f"{n} [{k}] {r['outcome']} {r.get('wall_s', 0):.2f} s: {r.get('error', '')}" for n, k, _, r in
                 result.findings]
    assert not described, "\n".join(described)


def test_a_slow_decode_is_judged_on_cpu_time_not_on_the_wall_clock_of_a_loaded_machine():
    from mocapbench.fuzz import FuzzResult, kill_seconds

    result = FuzzResult()
    result.add("raw-zstd", "header", b"a", {"outcome": "decoded", "wall_s": 9.0, "cpu_s": 0.2}, slow_s=5.0,
               output_limit=1 << 20)
    assert result.findings == []  # 9 s of wall on a loaded machine, 0.2 s of CPU: not slow
    result.add("raw-zstd", "header", b"b", {"outcome": "decoded", "wall_s": 6.0, "cpu_s": 5.5}, slow_s=5.0,
               output_limit=1 << 20)
    result.add("raw-zstd", "header", b"c", {"outcome": "timeout", "wall_s": 30.0}, slow_s=5.0, output_limit=1 << 20)
    assert [data for _, _, data, _ in result.findings] == [b"b", b"c"]
    assert kill_seconds(5.0) == 30.0 and kill_seconds(10.0) == 60.0
