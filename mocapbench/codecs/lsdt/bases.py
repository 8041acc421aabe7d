"""The committed LSDT bases (package data): loading, provenance and the fingerprint a stream carries.

The bases were trained on ``cmu_train`` by ``python -m mocapbench.benchmarks.lsdt.train --write-model``
(:mod:`.training`, Algorithm 1 of Hou et al. 2016); a stream names the bases it was coded with by
:func:`basis_fingerprint`, so a stream decoded with other bases is refused rather than decoded wrong.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from importlib import resources
from typing import Any

import numpy as np

__all__ = ["BASES_FILE", "COMMITTED_SPARSITIES", "basis_fingerprint", "committed_provenance", "load_committed_bases"]

#: The committed LSDT bases (package data), made by ``python -m mocapbench.benchmarks.lsdt.train``.
BASES_FILE = "models/lsdt_bases_v1.npz"
#: Sparsities P for which the committed file holds bases (§5.1, Fig. 4).
COMMITTED_SPARSITIES = (2, 5, 8, 11)

@lru_cache(maxsize=1)
def _committed_file() -> dict[str, np.ndarray]:
    path = resources.files("mocapbench").joinpath(BASES_FILE)
    with path.open("rb") as handle, np.load(handle) as data:
        return {key: np.array(data[key]) for key in data.files}


def load_committed_bases(sparsity: int = 8) -> np.ndarray:
    """The committed LSDT bases trained on ``cmu_train`` with sparsity P.

    Parameters
    ----------
    sparsity : int
        P, one of :data:`COMMITTED_SPARSITIES`.

    Returns
    -------
    ndarray, shape (3, 31, 31), float64
        ``B^x, B^y, B^z`` (rows are basis functions).
    """
    key = f"P{sparsity}"
    data = _committed_file()
    if key not in data:
        available = sorted(int(name[1:]) for name in data if name.startswith("P"))
        raise ValueError(f"The committed LSDT bases file {BASES_FILE} has no bases for P={sparsity}; it has P in {available}.")
    return data[key].copy()


def committed_provenance() -> dict[str, Any]:
    """The JSON sidecar of the committed bases (training clips, frames, iterations, objectives)."""
    path = resources.files("mocapbench").joinpath(BASES_FILE.replace(".npz", ".json"))
    return json.loads(path.read_text())


def basis_fingerprint(bases: np.ndarray) -> bytes:
    """First 8 bytes of the SHA-1 of the bases as little-endian float64: names the bases a stream was coded with."""
    return hashlib.sha1(np.ascontiguousarray(bases, dtype="<f8").tobytes()).digest()[:8]

