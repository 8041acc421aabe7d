"""Spatial decorrelation transforms of pose vectors: fixed (DCT, Haar DWT) and learned (LSDT, Hou et al. 2016)."""

from mocapbench.transforms.lsdt import (
    LsdtResult,
    lsdt_objective,
    orthogonal_step,
    train_lsdt,
    train_lsdt_bases,
    truncate,
)
from mocapbench.transforms.spatial import dct_matrix, haar_dwt_matrix, is_orthogonal, spatial_basis

__all__ = [
    "LsdtResult",
    "dct_matrix",
    "haar_dwt_matrix",
    "is_orthogonal",
    "lsdt_objective",
    "orthogonal_step",
    "spatial_basis",
    "train_lsdt",
    "train_lsdt_bases",
    "truncate",
]
