"""The fuzz harness: hostile streams with valid CRCs against every registered decoder, each decode in a worker
process with a memory cap and a wall-clock kill (:mod:`.harness`; ``python -m mocapbench.fuzz``)."""

from mocapbench.fuzz.harness import (
    REGRESSION_DIR,
    FuzzResult,
    Fuzzer,
    decoded_bytes,
    edit_header,
    header_offsets,
    kill_seconds,
    memory_check,
    memory_motion,
    mutations,
    restamp,
    run_campaign,
    save_findings,
    seed_streams,
    traced_decode_peak,
)

__all__ = [
    "REGRESSION_DIR",
    "FuzzResult",
    "Fuzzer",
    "decoded_bytes",
    "edit_header",
    "header_offsets",
    "kill_seconds",
    "memory_check",
    "memory_motion",
    "mutations",
    "restamp",
    "run_campaign",
    "save_findings",
    "seed_streams",
    "traced_decode_peak",
]
