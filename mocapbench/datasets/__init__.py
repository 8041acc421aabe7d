"""Motion data sets read in place from ``../shared`` (never copied into the repository)."""

from mocapbench.datasets.cmu import (
    SPLITS,
    DataNotFoundError,
    clip_names,
    cmu_data_dir,
    load_clip,
    load_folder,
    load_split,
)

__all__ = ["SPLITS", "DataNotFoundError", "clip_names", "cmu_data_dir", "load_clip", "load_folder", "load_split"]
