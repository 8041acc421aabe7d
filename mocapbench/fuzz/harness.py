"""Fuzz every registered codec's decoder with hostile streams whose CRC is valid, each decode in a worker process.

A stream edited at random fails the container's CRC32 and never reaches a payload parser; every stream made here
has its payload length and CRC recomputed, so each edit reaches the codec's own parser. Four kinds of edits,
drawn in turn from a seeded generator (the same seed gives the same streams):

* ``header``: F, J, fps, the payload length and the name length set to boundary and absurd values;
* ``field``: at every payload offset, a 1-, 2-, 4- or 8-byte value written over the bytes there (0, all ones,
  the sign bit, +-1, large varints, float NaN/inf/1e300/5e-324);
* ``zstd``: every inner zstd frame decompressed, its content edited (bytes, values, truncated or extended),
  recompressed and spliced back with its length prefix fixed;
* ``random``: 1-16 random bytes replaced, bytes inserted or deleted, a chunk duplicated.

Each decode runs in a worker process (``resource.setrlimit(RLIMIT_AS)`` caps its address space) with a wall-clock
kill enforced by the parent (a worker that does not answer within ``kill_s``, 6 x the slow limit and at least
30 s, is killed and replaced). A decode is *slow* when its CPU time exceeds the slow limit (5 s): wall time on a
shared, loaded machine says more about the other processes than about the decoder. For every decode the
worker reports the outcome (decoded, a :class:`BitstreamError` subclass, any other exception, a crash), its wall
and CPU time, the growth of its peak resident memory over the decode (``/proc/self/clear_refs`` resets the peak)
and the bytes of the decoded arrays.

The same workers read hostile motion files (BVH, glTF, GLB, FBX) and model files (:mod:`.surfaces`): a job's
target is a codec (decode the stream) or a surface (write the input to a file in the worker's empty folder and
read it as ``compress`` or ``--model`` would); :meth:`FuzzResult.surface_table` counts them per surface.

Targets: 0 outcomes other than decoded or ``BitstreamError``; 0 decodes above the limits; 0 decodes
over 5 s; decode memory at most 2 x the output arrays + a constant; for the files, 0 outcomes other than a motion,
a loaded model that codes, or the surface's one-line error, none over 5 s or the limits. Every other outcome is a
*finding*, written to ``tests/fuzz_regressions/<codec>-<hash>.mcb`` (or ``<surface>-<hash>.<suffix>``,
``--save-findings``) where ``tests/test_fuzz.py`` decodes or reads it in every run.

Run ``python -m mocapbench.fuzz --per-codec 8000 --per-surface 2000`` (the long run); the test suite runs a
bounded one under the ``fuzz`` marker (``pytest -m fuzz``).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import pickle
import resource
import select
import struct
import subprocess
import sys
import time
import warnings
import zlib
from collections import Counter, defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "restamp",
    "edit_header",
    "header_offsets",
    "mutations",
    "seed_streams",
    "FuzzResult",
    "Fuzzer",
    "run_campaign",
    "REGRESSION_DIR",
    "decoded_bytes",
    "traced_decode_peak",
    "memory_motion",
    "memory_check",
]

REGRESSION_DIR = Path(__file__).resolve().parents[2] / "tests" / "fuzz_regressions"
#: Limits every fuzz decode runs under: small enough that a worker stays well inside its memory cap.
FUZZ_OUTPUT_BYTES = 256 << 20
_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
_PREFIX = struct.Struct("<4sBI")


# -- editing a stream while keeping it well-formed outside -------------------------------------------------------


def header_offsets(data: bytes) -> dict[str, int]:
    """Byte offsets of the container fields of ``data`` (``name_length``, ``frames``, ``joints``, ``fps``,
    ``payload_length``, ``payload``; ``unit`` and ``up_axis`` from format version 2 on)."""
    name_length = data[_PREFIX.size]
    fields = _PREFIX.size + 1 + name_length
    offsets = {"name_length": _PREFIX.size, "frames": fields, "joints": fields + 4, "fps": fields + 6}
    if data[4] >= 2:
        offsets.update(unit=fields + 14, up_axis=fields + 18, payload_length=fields + 19, payload=fields + 23)
    else:
        offsets.update(payload_length=fields + 14, payload=fields + 18)
    return offsets


def restamp(data: bytes, *, fix_length: bool = True) -> bytes:
    """``data`` with its payload length (unless ``fix_length`` is False) and CRC32 recomputed."""
    data = bytearray(data)
    if len(data) < _PREFIX.size + 1:
        return bytes(data)
    offsets = header_offsets(bytes(data))
    if fix_length and len(data) >= offsets["payload"]:
        struct.pack_into("<I", data, offsets["payload_length"], len(data) - offsets["payload"])
    struct.pack_into("<I", data, 5, zlib.crc32(bytes(data[_PREFIX.size :])))
    return bytes(data)


def edit_header(data: bytes, **fields) -> bytes:
    """A copy of ``data`` with container fields replaced (``frames``, ``joints``, ``fps``) and the CRC fixed."""
    out = bytearray(data)
    offsets = header_offsets(data)
    formats = {"frames": "<I", "joints": "<H", "fps": "<d", "payload_length": "<I", "unit": "<f", "up_axis": "<c"}
    for name, value in fields.items():
        struct.pack_into(formats[name], out, offsets[name], value)
    return restamp(bytes(out), fix_length="payload_length" not in fields)


_INT_VALUES = (0, 1, 2, 3, 7, 8, 15, 16, 31, 255, 256, 4095, 4096, 65535, 65536, 10**6, 10**7, 10**8, 2**31 - 1, 2**32 - 1)
_FPS_VALUES = (0.0, -1.0, 5e-324, 1e-300, 1e-4, 1e-3, 1e5, 1e6, 1e308, float("inf"), float("nan"), 120.0)
_FIELD_VALUES: tuple[bytes, ...] = (
    b"\x00",
    b"\xff",
    b"\x7f",
    b"\x80",
    b"\xff\xff\xff\x0f",  # varint 2**28 - 1
    b"\xff\xff\xff\xff\xff\xff\xff\xff\x7f",  # varint 2**63 - 1
    b"\x80\x80\x80\x80\x10",  # varint 2**32
    struct.pack("<H", 0xFFFF),
    struct.pack("<I", 0xFFFFFFFF),
    struct.pack("<I", 0x7FFFFFFF),
    struct.pack("<f", float("nan")),
    struct.pack("<f", float("inf")),
    struct.pack("<f", 3e38),
    struct.pack("<f", 0.0),
    struct.pack("<d", float("nan")),
    struct.pack("<d", 1e300),
    struct.pack("<d", 5e-324),
    struct.pack("<d", -1.0),
    struct.pack("<d", 0.0),
)


def _header_mutation(data: bytes, rng: np.random.Generator) -> bytes:
    offsets = header_offsets(data)
    which = rng.choice(["frames", "joints", "fps", "payload_length", "name_length", "version", "unit", "up_axis"])
    frames, joints = struct.unpack_from("<IH", data, offsets["frames"])
    if which in ("unit", "up_axis") and "unit" not in offsets:
        which = "fps"
    if which == "unit":
        return edit_header(data, unit=float(rng.choice([0.0, -1.0, 1e-30, 2.54, 1e6, 1e7, 3e38, *_FPS_VALUES[-3:]])))
    if which == "up_axis":
        return edit_header(data, up_axis=bytes([int(rng.choice([0, ord("?"), ord("x"), ord("w"), 255]))]))
    if which == "frames":
        value = int(rng.choice([*_INT_VALUES, frames - 1, frames + 1, 2 * frames, frames // 2]))
        return edit_header(data, frames=int(np.clip(value, 0, 2**32 - 1)))
    if which == "joints":
        value = int(rng.choice([*(v for v in _INT_VALUES if v < 65536), joints - 1, joints + 1, 2 * joints, 1]))
        return edit_header(data, joints=int(np.clip(value, 0, 65535)))
    if which == "fps":
        return edit_header(data, fps=float(rng.choice(_FPS_VALUES)))
    if which == "payload_length":
        return edit_header(data, payload_length=int(rng.choice(_INT_VALUES)))
    out = bytearray(data)
    if which == "name_length":
        out[offsets["name_length"]] = int(rng.integers(0, 256))
    else:
        out[4] = int(rng.integers(0, 256))
    return restamp(bytes(out), fix_length=False)


def _field_mutation(data: bytes, rng: np.random.Generator, offset: int | None = None) -> bytes:
    start = header_offsets(data)["payload"]
    if len(data) <= start:
        return _random_mutation(data, rng)
    offset = int(rng.integers(start, len(data))) if offset is None else offset
    out = bytearray(data)
    kind = int(rng.integers(0, 4))
    if kind == 0:  # a value from the table
        value = _FIELD_VALUES[int(rng.integers(len(_FIELD_VALUES)))]
    elif kind == 1:  # +-1 on one byte
        value = bytes([(out[offset] + int(rng.choice([-1, 1]))) % 256])
    elif kind == 2:  # +-1 on a little-endian u32
        width = min(4, len(out) - offset)
        number = int.from_bytes(out[offset : offset + width], "little") + int(rng.choice([-1, 1]))
        value = (number % (1 << (8 * width))).to_bytes(width, "little")
    else:  # one bit
        value = bytes([out[offset] ^ (1 << int(rng.integers(8)))])
    out[offset : offset + len(value)] = value[: len(out) - offset]
    return restamp(bytes(out))


def _varint_before(data: bytes, end: int, value: int) -> tuple[int, int] | None:
    """``(start, end)`` of a LEB128 varint ending at ``end`` that encodes ``value``, if there is one."""
    for length in range(1, 6):
        start = end - length
        if start < 0:
            return None
        number, ok = 0, True
        for i, byte in enumerate(data[start:end]):
            last = i == length - 1
            if (byte & 0x80 == 0) != last:
                ok = False
                break
            number |= (byte & 0x7F) << (7 * i)
        if ok and number == value:
            return start, end
    return None


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


def zstd_frames(data: bytes, start: int) -> list[tuple[int, int]]:
    """``(offset, length)`` of every complete zstd frame found in ``data[start:]``."""
    import zstandard

    frames = []
    position = data.find(_ZSTD_MAGIC, start)
    while position >= 0:
        try:
            decompressor = zstandard.ZstdDecompressor().decompressobj()
            decompressor.decompress(data[position:])
            if decompressor.eof:
                length = len(data) - position - len(decompressor.unused_data)
                frames.append((position, length))
        except zstandard.ZstdError:
            pass
        position = data.find(_ZSTD_MAGIC, position + 1)
    return frames


def _zstd_mutation(data: bytes, rng: np.random.Generator) -> bytes:
    import zstandard

    frames = zstd_frames(data, header_offsets(data)["payload"])
    if not frames:
        return _field_mutation(data, rng)
    offset, length = frames[int(rng.integers(len(frames)))]
    content = bytearray(zstandard.ZstdDecompressor().decompress(data[offset : offset + length]))
    kind = int(rng.integers(0, 4))
    if kind == 0 and content:  # values written into the content
        for _ in range(int(rng.integers(1, 4))):
            at = int(rng.integers(len(content)))
            value = _FIELD_VALUES[int(rng.integers(len(_FIELD_VALUES)))]
            content[at : at + len(value)] = value[: len(content) - at]
    elif kind == 1 and content:  # truncated
        del content[int(rng.integers(len(content))) :]
    elif kind == 2:  # extended
        content += bytes(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8))
    elif content:  # random bytes
        for _ in range(int(rng.integers(1, 8))):
            content[int(rng.integers(len(content)))] = int(rng.integers(256))
    frame = zstandard.ZstdCompressor(level=3, write_content_size=True, write_checksum=False).compress(bytes(content))
    out = data[:offset] + frame + data[offset + length :]
    # Fix the blob length in front of the frame (varint just before it, or before a one-byte width prefix).
    for prefix_end, extra in ((offset, 0), (offset - 1, 1)):
        found = _varint_before(data, prefix_end, length + extra)
        if found is not None:
            begin, end = found
            out = data[:begin] + _varint(len(frame) + extra) + data[end:offset] + frame + data[offset + length :]
            break
    return restamp(out)


def _random_mutation(data: bytes, rng: np.random.Generator) -> bytes:
    start = min(header_offsets(data)["payload"], len(data))
    out = bytearray(data)
    kind = int(rng.integers(0, 4))
    span = max(len(out) - start, 1)
    at = start + int(rng.integers(span))
    if kind == 0:
        for _ in range(int(rng.integers(1, 17))):
            if len(out) > start:
                out[start + int(rng.integers(len(out) - start))] = int(rng.integers(256))
    elif kind == 1:
        out[at:at] = bytes(rng.integers(0, 256, int(rng.integers(1, 9)), dtype=np.uint8))
    elif kind == 2:
        del out[at : at + int(rng.integers(1, 9))]
    else:
        size = int(rng.integers(1, 33))
        out[at:at] = out[at : at + size]
    return restamp(bytes(out))


KINDS = ("header", "field", "zstd", "random")


def mutations(seed_stream: bytes, count: int, seed: int) -> Iterator[tuple[str, bytes]]:
    """``count`` hostile variants of ``seed_stream``: ``(kind, stream)``, kinds in turn, deterministic in ``seed``.

    ``field`` edits walk the payload offsets in order (every offset is edited before any is edited twice).
    """
    rng = np.random.default_rng(seed)
    payload_start = header_offsets(seed_stream)["payload"]
    offsets = range(payload_start, len(seed_stream))
    field_index = 0
    for index in range(count):
        kind = KINDS[index % len(KINDS)]
        if kind == "header":
            yield kind, _header_mutation(seed_stream, rng)
        elif kind == "field":
            offset = offsets[field_index % len(offsets)] if len(offsets) else None
            field_index += 1
            yield kind, _field_mutation(seed_stream, rng, offset)
        elif kind == "zstd":
            yield kind, _zstd_mutation(seed_stream, rng)
        else:
            yield kind, _random_mutation(seed_stream, rng)


# -- seed streams -----------------------------------------------------------------------------------------------


def seed_streams(names: list[str]) -> dict[str, list[bytes]]:
    """Valid streams per codec: its ``smoke_params`` on two short synthetic motions (24 and 61 frames) and, for a
    codec that carries a game rig's tracks, a third: a game rig (a translated pelvis, a stretching spine and, where
    the codec carries scale, a scaled chest), so that the streams' track sections and flags are fuzzed too."""
    from mocapbench.codecs import CODECS, create
    from mocapbench.synthetic import sinusoidal_motion
    from mocapbench.synthetic.game import game_rig_motion

    motions = [sinusoidal_motion(num_frames=24, seed=3), sinusoidal_motion(num_frames=61, seed=4)]
    streams = {}
    for name in names:
        codec = create(name, **CODECS[name].smoke_params)
        streams[name] = [codec.encode(motion) for motion in motions]
        carried = CODECS[name].carries_tracks
        if "translations" in carried:
            rig = game_rig_motion(num_frames=30, seed=5, stretch_cm=2.0, scale=1.2 if "scales" in carried else 1.0)
            streams[name].append(codec.encode(rig))
    return streams


# -- the worker (one process; the parent sends (codec, stream) and reads one result per decode) ------------------


def _peak_rss() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
        return True
    except OSError:
        return False


def _current_rss() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _send(stream, obj) -> None:
    blob = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(struct.pack("<I", len(blob)) + blob)
    stream.flush()


def _receive(stream):
    size = stream.read(4)
    if len(size) < 4:
        return None
    return pickle.loads(stream.read(struct.unpack("<I", size)[0]))


def _worker_main() -> None:
    """Loop of a worker: read ``(target, input)``, decode the stream (target: a codec) or read the file (target: a
    surface of :mod:`.surfaces`), write a result dict."""
    memory_bytes = int(os.environ.get("MOCAPBENCH_FUZZ_AS_BYTES", "0"))
    if memory_bytes:
        resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    import tempfile

    from mocapbench.codecs import CODECS, BitstreamError, DecodeLimits, create
    from mocapbench.fuzz import surfaces

    limits = DecodeLimits(max_output_bytes=int(os.environ.get("MOCAPBENCH_FUZZ_OUTPUT_BYTES", FUZZ_OUTPUT_BYTES)))
    clean = (BitstreamError, *surfaces.clean_errors())
    folder = Path(tempfile.mkdtemp(prefix="mocapbench-fuzz-"))
    codecs = {}
    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    _send(stdout, {"ready": True})
    while True:
        message = _receive(stdin)
        if message is None:
            return
        name, data = message
        if name not in codecs and name not in surfaces.SURFACES:
            codecs[name] = create(name, **CODECS[name].smoke_params)
        before = _current_rss()
        resetable = _reset_peak()
        cpu0, wall0 = time.process_time(), time.perf_counter()
        result = {"outcome": "decoded", "error": "", "output_bytes": 0}
        caught = warnings.catch_warnings(record=True)
        seen = caught.__enter__()
        warnings.simplefilter("always")
        try:
            if name in surfaces.SURFACES:
                result["output_bytes"] = surfaces.read_input(name, data, folder, limits)
            else:
                decoded = codecs[name].decode(data, limits=limits)
                result["output_bytes"] = decoded_bytes(decoded)
                result["frames"], result["joints"] = decoded.positions.shape[:2]
                del decoded
        except clean as error:
            result["outcome"] = type(error).__name__
            result["error"] = str(error)[:300]
        except BaseException as error:  # noqa: BLE001 - every other outcome is a finding, reported as such
            result["outcome"] = f"other:{type(error).__name__}"
            result["error"] = str(error)[:300]
        finally:
            caught.__exit__(None, None, None)
        # A decode must be silent: a warning is a line the user sees that says nothing (a finding). Readers may
        # warn through their own channel (read_motion's warnings list), never through Python's warnings.
        if seen and not result["outcome"].startswith("other:"):
            result["outcome"] = f"other:{seen[0].category.__name__}"
            result["error"] = str(seen[0].message)[:300]
        result["wall_s"] = time.perf_counter() - wall0
        result["cpu_s"] = time.process_time() - cpu0
        result["memory_bytes"] = max(_peak_rss() - before, 0) if resetable else -1
        _send(stdout, result)


class _Worker:
    def __init__(self, memory_bytes: int, output_bytes: int) -> None:
        env = dict(os.environ, MOCAPBENCH_FUZZ_AS_BYTES=str(memory_bytes),
                   MOCAPBENCH_FUZZ_OUTPUT_BYTES=str(output_bytes), OMP_NUM_THREADS="1",
                   OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        self.process = subprocess.Popen(
            [sys.executable, "-c", "from mocapbench.fuzz.harness import _worker_main; _worker_main()"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env,
        )
        ready = self._read(120.0)
        if not ready:
            raise RuntimeError("fuzz worker did not start")

    def _read(self, timeout: float):
        ready, _, _ = select.select([self.process.stdout], [], [], timeout)
        if not ready:
            return None
        return _receive(self.process.stdout)

    def decode(self, name: str, data: bytes, timeout: float) -> dict:
        _send(self.process.stdin, (name, data))
        result = self._read(timeout)
        if result is None:
            if self.process.poll() is None:
                self.close()
                return {"outcome": "timeout", "error": f"no answer within {timeout} s", "wall_s": timeout}
            return {"outcome": "crash", "error": f"worker exited with {self.process.returncode}", "wall_s": 0.0}
        return result

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()


# -- the campaign -----------------------------------------------------------------------------------------------


@dataclass
class FuzzResult:
    """Counts and extremes per codec, and the findings (codec, kind, stream, result)."""

    counts: dict[str, Counter] = field(default_factory=lambda: defaultdict(Counter))
    max_wall_s: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    max_cpu_s: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    max_memory: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    max_excess: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # memory - 2 x output, bytes
    slow: Counter = field(default_factory=Counter)  # inputs over the CPU limit that still answered
    over_output: Counter = field(default_factory=Counter)  # inputs whose output exceeded the output limit
    findings: list[tuple[str, str, bytes, dict]] = field(default_factory=list)

    @property
    def total(self) -> int:
        return sum(sum(c.values()) for c in self.counts.values())

    def add(self, name: str, kind: str, data: bytes, result: dict, *, slow_s: float, output_limit: int) -> None:
        outcome = result["outcome"]
        self.counts[name][outcome] += 1
        self.max_wall_s[name] = max(self.max_wall_s[name], result.get("wall_s", 0.0))
        self.max_cpu_s[name] = max(self.max_cpu_s[name], result.get("cpu_s", 0.0))
        memory = result.get("memory_bytes", 0)
        self.max_memory[name] = max(self.max_memory[name], memory)
        self.max_excess[name] = max(self.max_excess[name], memory - 2 * result.get("output_bytes", 0))
        if result.get("cpu_s", 0.0) > slow_s and outcome != "timeout":
            self.slow[name] += 1
        if result.get("output_bytes", 0) > output_limit:
            self.over_output[name] += 1
        bad = (
            outcome.startswith("other:") or outcome in ("timeout", "crash")
            or result.get("cpu_s", 0.0) > slow_s or result.get("output_bytes", 0) > output_limit
        )
        if bad:
            self.findings.append((name, kind, data, result))

    def table(self) -> str:
        """A markdown table: one row per codec, then the total."""
        lines = [
            "| codec | streams | decoded | BitstreamError | limit errors | other | timeouts | crashes | max wall s "
            "| max CPU s | max memory MB | max (memory - 2 x output) MB |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        total = Counter()
        for name in sorted(self.counts):
            c = self.counts[name]
            row = self._row(c)
            total.update(c)
            lines.append(
                f"| {name} | {row[0]} | {row[1]} | {row[2]} | {row[3]} | {row[4]} | {row[5]} | {row[6]} "
                f"| {self.max_wall_s[name]:.3f} | {self.max_cpu_s[name]:.3f} | {self.max_memory[name] / 2**20:.1f} "
                f"| {self.max_excess[name] / 2**20:.1f} |"
            )
        row = self._row(total)
        lines.append(
            f"| **all** | {row[0]} | {row[1]} | {row[2]} | {row[3]} | {row[4]} | {row[5]} | {row[6]} "
            f"| {max(self.max_wall_s.values(), default=0):.3f} | {max(self.max_cpu_s.values(), default=0):.3f} "
            f"| {max(self.max_memory.values(), default=0) / 2**20:.1f} "
            f"| {max(self.max_excess.values(), default=0) / 2**20:.1f} |"
        )
        return "\n".join(lines)

    def surface_table(self) -> str:
        """A markdown table per surface (streams of every codec; BVH, glTF and GLB, FBX, model files).

        Columns: inputs; accepted (decoded or read); clean errors (a ``BitstreamError``, or the surface's one-line
        error); other exceptions (any other class, a Python warning); hangs (over the CPU limit, or killed at the
        wall-clock limit); memory failures (``MemoryError``, a crashed worker, an output over the limit); the peak
        memory growth and the CPU time of the worst input.
        """
        from mocapbench.fuzz.surfaces import SURFACE_LABELS

        groups: dict[str, list[str]] = defaultdict(list)
        for name in self.counts:
            groups[SURFACE_LABELS.get(name, "streams")].append(name)
        lines = [
            "| surface | inputs | accepted | clean errors | other exceptions | hangs | memory failures "
            "| worst peak memory MB | worst CPU s |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        order = ["streams", *dict.fromkeys(SURFACE_LABELS.values())]
        for label in [label for label in order if label in groups]:
            c = Counter()
            for name in groups[label]:
                c.update(self.counts[name])
            memory_failures = c.get("crash", 0) + c.get("other:MemoryError", 0) + sum(
                self.over_output[name] for name in groups[label])
            other = sum(v for k, v in c.items() if k.startswith("other:") and k != "other:MemoryError")
            hangs = c.get("timeout", 0) + sum(self.slow[name] for name in groups[label])
            clean = sum(v for k, v in c.items()
                        if k not in ("decoded", "timeout", "crash") and not k.startswith("other:"))
            lines.append(
                f"| {label} | {sum(c.values())} | {c.get('decoded', 0)} | {clean} | {other} | {hangs} "
                f"| {memory_failures} | {max(self.max_memory[n] for n in groups[label]) / 2**20:.1f} "
                f"| {max(self.max_cpu_s[n] for n in groups[label]):.2f} |"
            )
        return "\n".join(lines)

    @staticmethod
    def _row(c: Counter) -> tuple[int, ...]:
        limit = c.get("DecodeLimitError", 0)
        other = sum(v for k, v in c.items() if k.startswith("other:"))
        bitstream = sum(v for k, v in c.items() if k not in ("decoded", "timeout", "crash") and not k.startswith("other:"))
        return (sum(c.values()), c.get("decoded", 0), bitstream, limit, other, c.get("timeout", 0), c.get("crash", 0))


class Fuzzer:
    """A pool of decode workers; :meth:`decode_all` spreads (codec, stream) jobs over them."""

    def __init__(self, workers: int = 2, memory_bytes: int = 3 << 30, output_bytes: int = FUZZ_OUTPUT_BYTES,
                 timeout_s: float = 5.0) -> None:
        self.memory_bytes, self.output_bytes, self.timeout_s = memory_bytes, output_bytes, timeout_s
        self.workers = [_Worker(memory_bytes, output_bytes) for _ in range(workers)]

    def _replace(self, index: int) -> None:
        self.workers[index].close()
        self.workers[index] = _Worker(self.memory_bytes, self.output_bytes)

    def decode_all(self, jobs, on_result) -> None:
        """Decode every ``(codec, kind, stream)`` of ``jobs``; ``on_result(codec, kind, stream, result)`` each."""
        jobs = iter(jobs)
        busy: dict[int, tuple[str, str, bytes, float]] = {}
        by_fd = {w.process.stdout.fileno(): i for i, w in enumerate(self.workers)}

        def start(index: int) -> bool:
            job = next(jobs, None)
            if job is None:
                return False
            name, kind, data = job
            _send(self.workers[index].process.stdin, (name, data))
            busy[index] = (name, kind, data, time.monotonic())
            return True

        for index in range(len(self.workers)):
            start(index)
        while busy:
            now = time.monotonic()
            wait = max(0.0, min(t for *_, t in busy.values()) + self.timeout_s - now)
            fds = [self.workers[i].process.stdout.fileno() for i in busy]
            ready, _, _ = select.select(fds, [], [], wait)
            finished = []
            for fd in ready:
                index = by_fd[fd]
                result = _receive(self.workers[index].process.stdout)
                if result is None:
                    code = self.workers[index].process.wait()
                    result = {"outcome": "crash", "error": f"worker exited with {code}", "wall_s": 0.0}
                    self._replace(index)
                    by_fd = {w.process.stdout.fileno(): i for i, w in enumerate(self.workers)}
                finished.append((index, result))
            now = time.monotonic()
            for index, (name, kind, data, started) in list(busy.items()):
                if index not in [i for i, _ in finished] and now - started > self.timeout_s:
                    self._replace(index)
                    by_fd = {w.process.stdout.fileno(): i for i, w in enumerate(self.workers)}
                    finished.append((index, {"outcome": "timeout", "error": f"no answer within {self.timeout_s} s",
                                             "wall_s": now - started}))
            for index, result in finished:
                name, kind, data, _ = busy.pop(index)
                on_result(name, kind, data, result)
                start(index)

    def close(self) -> None:
        for worker in self.workers:
            worker.close()


def kill_seconds(timeout_s: float) -> float:
    """Wall seconds after which a decode is killed: 6 x the CPU limit ``timeout_s``, at least 30 s."""
    return max(30.0, 6.0 * timeout_s)


def run_campaign(names: list[str], per_codec: int, *, seed: int = 0, workers: int = 2, timeout_s: float = 5.0,
                 memory_bytes: int = 3 << 30, output_bytes: int = FUZZ_OUTPUT_BYTES, progress: bool = False,
                 kill_s: float | None = None, per_surface: int = 0,
                 surfaces: list[str] | None = None) -> FuzzResult:
    """Fuzz ``names`` with ``per_codec`` hostile streams each, and every file surface (:mod:`.surfaces`) with
    ``per_surface`` hostile files each; returns the counts, extremes and findings.

    A decode or read over ``timeout_s`` of CPU is a finding; one that has not answered after ``kill_s`` wall
    seconds (default :func:`kill_seconds`) is killed and counted as a timeout.
    """
    from mocapbench.fuzz.surfaces import SURFACES, file_mutations, seed_files

    streams = seed_streams(names)
    wanted = ([] if not per_surface else list(SURFACES) if surfaces is None else surfaces)
    files = seed_files(wanted) if wanted else {}
    result = FuzzResult()

    def split(seeds, count):
        return [count // len(seeds) + (i < count % len(seeds)) for i in range(len(seeds))]

    def jobs():
        for index, name in enumerate(names):
            seeds = streams[name]
            for seed_index, (stream, count) in enumerate(zip(seeds, split(seeds, per_codec))):
                for kind, data in mutations(stream, count, seed=hash((seed, index, seed_index)) & 0xFFFFFFFF):
                    yield name, kind, data
        for index, surface in enumerate(wanted):
            seeds = files.get(surface, [])
            for seed_index, (original, count) in enumerate(zip(seeds, split(seeds, per_surface) if seeds else [])):
                value = hash((seed, 1 << 20, index, seed_index)) & 0xFFFFFFFF  # ints only: hash() of a str varies by process
                for kind, data in file_mutations(surface, original, count, value):
                    yield surface, kind, data

    total = per_codec * len(names) + per_surface * sum(1 for surface in wanted if files.get(surface))
    done = [0]
    started = time.monotonic()

    def on_result(name, kind, data, outcome):
        result.add(name, kind, data, outcome, slow_s=timeout_s, output_limit=output_bytes)
        done[0] += 1
        if progress and done[0] % 1000 == 0:
            rate = done[0] / (time.monotonic() - started)
            print(f"fuzz: {done[0]}/{total} inputs, {rate:.0f}/s, "
                  f"{len(result.findings)} findings", file=sys.stderr, flush=True)

    fuzzer = Fuzzer(workers, memory_bytes, output_bytes, kill_seconds(timeout_s) if kill_s is None else kill_s)
    try:
        fuzzer.decode_all(jobs(), on_result)
    finally:
        fuzzer.close()
    return result


def decoded_bytes(decoded) -> int:
    """Bytes of everything a decode returns: the positions, and the motion's quaternions and root positions when
    the codec decodes rotations (what :func:`mocapbench.codecs.limits.output_bytes` bounds)."""
    size = decoded.positions.nbytes
    if decoded.motion is not None:
        size += decoded.motion.rotations.nbytes + decoded.motion.root_positions.nbytes
    return size


def traced_decode_peak(codec, data: bytes) -> tuple[int, int]:
    """``(peak, output)`` bytes of one decode measured by :mod:`tracemalloc` (which counts numpy's arrays).

    ``peak`` is the largest growth of traced memory over the decode (the output included), ``output`` is
    :func:`decoded_bytes`. Unlike the resident-memory figures of :func:`memory_check` it does not depend on the
    allocator or the machine, so a test can hold a decoder to ``peak <= 2 output + constant``. Memory that C
    libraries allocate themselves (zstd's window, BLAS buffers) is not seen; decode once before measuring so that
    lazy imports are not counted.
    """
    import gc
    import tracemalloc

    gc.collect()
    started = not tracemalloc.is_tracing()
    if started:
        tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        decoded = codec.decode(data)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        if started:
            tracemalloc.stop()
    return peak, decoded_bytes(decoded)


#: Frames of the short stream each memory-check worker decodes first, so that lazy imports and caches (a
#: constant) are not counted as growth with the clip.
_WARMUP_FRAMES = 120
#: The root walks at most this far over a memory-check motion (cm): pga-ik's and the neural codecs' numeric range
#: (50 m, 500 m) must hold however long the motion is.
_MEMORY_WALK_CM = 2000.0


def memory_motion(num_frames: int, seed: int = 5):
    """The synthetic motion of the memory check: 31 joints at 120 fps, its root walking at most 20 m."""
    from mocapbench.synthetic import SyntheticConfig, sinusoidal_motion

    speed = min(SyntheticConfig.speed_cm_s, _MEMORY_WALK_CM * SyntheticConfig.fps / max(num_frames, 1))
    return sinusoidal_motion(num_frames=num_frames, seed=seed, speed_cm_s=speed)


def memory_check(names: list[str], num_frames: int, *, timeout_s: float = 600.0) -> str:
    """Decode one valid ``num_frames``-frame stream per codec in a fresh worker; a markdown table of the peak memory.

    The target: the growth of the worker's peak resident memory over the decode is at most twice
    the decoded arrays plus a constant. "Decoded arrays" are everything a decode returns: the positions
    ``(F, J, 3)`` float64, and for the codecs that decode rotations the motion's quaternions ``(F, J, 4)`` and
    root positions ``(F, 3)`` as well (:func:`mocapbench.codecs.limits.output_bytes`). The stream is the codec's
    ``smoke_params`` on :func:`memory_motion`. Each worker first decodes a 120-frame stream of the same codec, so
    that what a first decode loads once (lazy imports, caches) is not counted; the column ``growth - 2 x arrays``
    is the constant the target allows (a window's temporaries for the windowed codecs).
    """
    from mocapbench.codecs import CODECS, create

    motion = memory_motion(num_frames)
    warmup = memory_motion(_WARMUP_FRAMES)
    lines = ["| codec | frames | decoded arrays MB | peak memory growth MB | growth / arrays "
             "| growth - 2 x arrays MB | decode wall s | decode CPU s |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name in names:
        codec = create(name, **CODECS[name].smoke_params)
        try:
            data, small = codec.encode(motion), codec.encode(warmup)
        except Exception as error:  # noqa: BLE001 - one row says why, the table goes on
            lines.append(f"| {name} | {num_frames} | - | - | - | - | - | encode failed: {type(error).__name__}: "
                         f"{str(error)[:200]} |")
            continue
        fuzzer = Fuzzer(workers=1, memory_bytes=16 << 30, output_bytes=8 << 30, timeout_s=timeout_s)
        try:
            results: list[dict] = []
            fuzzer.decode_all([(name, "warm-up", small), (name, "valid", data)],
                              lambda *args: results.append(args[3]))
        finally:
            fuzzer.close()
        r = results[-1]
        if r["outcome"] != "decoded":
            lines.append(f"| {name} | {num_frames} | - | - | - | - | {r.get('wall_s', 0):.1f} "
                         f"| {r['outcome']}: {r['error']} |")
            continue
        out, grow = r["output_bytes"] / 2**20, r["memory_bytes"] / 2**20
        lines.append(f"| {name} | {num_frames} | {out:.1f} | {grow:.1f} | {grow / out:.2f} | {grow - 2 * out:.1f} "
                     f"| {r['wall_s']:.2f} | {r['cpu_s']:.2f} |")
    return "\n".join(lines)


def save_findings(result: FuzzResult, folder: Path = REGRESSION_DIR) -> list[Path]:
    """Write each finding's input to ``folder/<codec or surface>-<sha1 12><suffix>`` (``.mcb`` for a stream, the
    surface's suffix for a file; kept by name, duplicates once)."""
    from mocapbench.fuzz.surfaces import SURFACES

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, _, data, _ in result.findings:
        path = folder / f"{name}-{hashlib.sha1(data).hexdigest()[:12]}{SURFACES.get(name, '.mcb')}"
        if not path.exists():
            path.write_bytes(data)
            written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    from mocapbench.codecs import CODECS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-codec", type=int, default=8000, help="hostile streams per codec (default 8000)")
    parser.add_argument("--codecs", nargs="*", default=None, help="codec names (default: every registered codec)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--timeout-s", type=float, default=5.0,
                        help="a decode over this many CPU seconds is a finding (killed after 6x, >= 30 s, of wall)")
    parser.add_argument("--memory-mb", type=int, default=3072, help="address-space cap of each worker (RLIMIT_AS)")
    parser.add_argument("--output-mb", type=int, default=FUZZ_OUTPUT_BYTES >> 20, help="DecodeLimits.max_output_bytes")
    parser.add_argument("--save-findings", action="store_true", help=f"write findings to {REGRESSION_DIR}")
    parser.add_argument("--per-surface", type=int, default=2000,
                        help="hostile files per surface: BVH, glTF, GLB, FBX, model files (0: streams only)")
    parser.add_argument("--surfaces", nargs="*", default=None, help="file surfaces (default: all)")
    parser.add_argument("--memory-frames", type=int, default=0,
                        help="instead of fuzzing: decode one valid stream of this many frames per codec, print memory")
    args = parser.parse_args(argv)
    names = sorted(CODECS) if not args.codecs else args.codecs
    unknown = sorted(set(names) - set(CODECS))
    if unknown:
        parser.error(f"unknown codecs {unknown}; registered: {sorted(CODECS)}")
    if args.memory_frames:
        print(memory_check(names, args.memory_frames))
        print(f"\nload average {os.getloadavg()[0]:.2f}")
        return 0
    started, cpu = time.perf_counter(), time.process_time()
    result = run_campaign(names, args.per_codec, seed=args.seed, workers=args.workers, timeout_s=args.timeout_s,
                          memory_bytes=args.memory_mb << 20, output_bytes=args.output_mb << 20, progress=True,
                          per_surface=args.per_surface, surfaces=args.surfaces)
    print(result.table())
    print()
    print(result.surface_table())
    print(f"\n{result.total} inputs in {time.perf_counter() - started:.0f} s wall ({args.workers} workers; "
          f"parent CPU {time.process_time() - cpu:.0f} s), load average {os.getloadavg()[0]:.2f}; "
          f"{len(result.findings)} findings")
    for name, kind, data, outcome in result.findings[:20]:
        print(f"  {name} [{kind}] {outcome['outcome']} {outcome.get('wall_s', 0):.2f} s: {outcome.get('error', '')}")
    if args.save_findings and result.findings:
        for path in save_findings(result):
            print(f"  saved {path}")
    return 1 if result.findings else 0


if __name__ == "__main__":
    sys.exit(main())
