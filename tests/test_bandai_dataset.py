"""The Bandai Namco dataset configs: splits from the manifest, files named without parsing, bad folders in one line."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from mocapbench.datasets import bandai
from mocapbench.datasets.cmu import DataNotFoundError
from mocapbench.experiments import datasets

CONFIGS = Path(__file__).resolve().parents[1] / "mocapbench" / "configs" / "dataset"


def _folder(tmp_path: Path, rows: list[tuple[str, int, str]]) -> Path:
    (tmp_path / "bvh").mkdir()
    lines = ["file,content,style,take,frames,fps,joints,bytes,sha256,split"]
    for name, frames, split in rows:
        (tmp_path / "bvh" / f"{name}.bvh").write_text("HIERARCHY\n")
        lines.append(f"bvh/{name}.bvh,walk,happy,001,{frames},30,22,1,0,{split}")
    (tmp_path / "manifest.csv").write_text("\n".join(lines) + "\n")
    return tmp_path


def test_splits_follow_the_manifest(tmp_path):
    folder = _folder(tmp_path, [("a", 10, "test"), ("b", 20, "train"), ("c", 30, "test")])
    assert [(n, f) for n, f, _ in bandai.clip_files("bandai_test", folder)] == [("a", 10), ("c", 30)]
    assert [n for n, _, _ in bandai.clip_files("bandai_train", folder)] == ["b"]
    assert [n for n, _, _ in bandai.clip_files("bandai_all", folder)] == ["a", "b", "c"]
    spec = {"name": "t", "kind": "bandai", "split": "bandai_test", "data_dir": str(folder),
            "train": {"split": "bandai_train"}}
    assert [ref.frames for ref in datasets.catalogue(spec)] == [10, 30]
    assert datasets.describe_training(spec) == "Bandai Namco BVH bandai_train"
    assert datasets.bandai_used(spec) and not datasets.cmu_used(spec)


def test_bad_folders_and_splits_are_one_line(tmp_path):
    with pytest.raises(DataNotFoundError, match="Looked in: .*nowhere"):
        bandai.clip_files("bandai_test", tmp_path / "nowhere")
    folder = _folder(tmp_path, [("a", 10, "test")])
    (folder / "bvh" / "a.bvh").unlink()
    with pytest.raises(DataNotFoundError, match=r"line 2: .*a\.bvh is not a BVH file inside"):
        bandai.clip_files("bandai_test", folder)
    with pytest.raises(datasets.DatasetError, match="`split` must be one of"):
        datasets.catalogue({"name": "t", "kind": "bandai", "split": "test", "data_dir": str(folder)})


def test_the_shipped_configs_name_the_split_files(bandai_dir):
    counts = {}
    for split in ("test", "train", "all"):
        spec = yaml.safe_load((CONFIGS / f"bandai_{split}.yaml").read_text())
        refs = datasets.catalogue(spec)
        counts[split] = (len(refs), sum(ref.frames for ref in refs))
    assert counts == {"test": (39, 8457), "train": (133, 23309), "all": (172, 31766)}
