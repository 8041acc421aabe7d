"""Dump the chunk units of mcb-rot streams, as the Python decoder reads them, for ``runtime/bench/bench_units.c``.

Each chunk's unit (its coefficients and corrections) is recorded through a hook on the decoder's ``decode_unit``:
the classes it is decoded with, the values it gives and its bytes in the stream (the size varint, the rANS data,
the sign and raw bits). Run with ``MOCAPBENCH_NATIVE=0`` (the native runtime decodes without that hook).

    PYTHONPATH=. MOCAPBENCH_NATIVE=0 python runtime/tools/dump_units.py OUT.bin STREAM.mcb...

``OUT.bin``, one record per unit: u32 values n | u32 bytes | n u8 classes | n i32 values (little-endian); before
each stream's units a mark u32 0xFFFFFFFF | u32 the stream's index (so that a reader can replay a clip's units in
the order random access meets them).
"""

from __future__ import annotations

import os
import struct
import sys
from pathlib import Path

import numpy as np


def main(argv: list[str]) -> None:
    if len(argv) < 2:
        sys.exit("usage: dump_units.py OUT.bin STREAM.mcb...")
    if os.environ.get("MOCAPBENCH_NATIVE") != "0":
        sys.exit("dump_units.py: set MOCAPBENCH_NATIVE=0 (the native runtime decodes without the Python units).")
    out = Path(argv[0])
    if out.exists():
        sys.exit(f"dump_units.py: {out} exists (not overwritten).")
    from mocapbench.codecs import create
    from mocapbench.codecs.mcb_rot import decoder

    units = []
    decode_unit = decoder.decode_unit

    def recording(reader, classes, tables, what, limit=None):
        start = reader.offset
        values = decode_unit(reader, classes, tables, what, limit)
        units.append((np.asarray(classes, np.uint8), values.astype("<i4"), reader.offset - start))
        return values

    decoder.decode_unit = recording
    with open(out, "xb") as file:
        for index, path in enumerate(argv[1:]):
            units.clear()
            create("mcb-rot").decode(Path(path).read_bytes())
            file.write(struct.pack("<II", 0xFFFFFFFF, index))
            for classes, values, size in units:
                file.write(struct.pack("<II", len(classes), size) + classes.tobytes() + values.tobytes())
            print(f"{path}: {len(units)} units, {sum(len(u[0]) for u in units)} values", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1:])
