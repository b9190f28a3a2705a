"""The BSDS experiments on a new user's runs: a subset never overwrites the full-set results, a changed
label file is computed again (not read back from the cache), a bad label file ends the run with one
line naming it, and impossible option values are argparse errors.

Most tests build a tiny synthetic bsds-fg folder in tmp_path (two 10 x 12 images and their labels);
the end-to-end ones need the dataset and skip without it."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from snn_fg.errors import InputError
from snn_fg.scoring.groundtruth import load_bsds_fg

REPO = Path(__file__).resolve().parents[1]
SHAPE = (10, 12)


def _labels(value=1):
    fg = np.zeros((2, *SHAPE), np.int8)
    fg[:, 5, :] = value
    fg[:, 6, :] = -value
    return fg


def fake_root(tmp_path, ids=("1", "2")) -> Path:
    """A bsds-fg folder: ``images/<id>.jpg`` (10 x 12 grey) and ``labels/<id>.npz`` (two labellers)."""
    root = tmp_path / "bsds-fg"
    (root / "images").mkdir(parents=True)
    (root / "labels").mkdir()
    for i in ids:
        cv2.imwrite(str(root / "images" / f"{i}.jpg"), np.full(SHAPE, 128, np.uint8))
        np.savez(root / "labels" / f"{i}.npz", fg=_labels(), labellers=np.array([1, 2], np.int32))
    return root


@pytest.mark.parametrize(
    "content, problem",
    [
        ({"fg": np.zeros((2, 10, 10), np.int8)}, "10 x 10 but the image 1.jpg is 10 x 12"),
        ({"fg": np.zeros((2, *SHAPE), np.float32)}, "integer array"),
        ({"fg": np.full((2, *SHAPE), 2, np.int8)}, "only -1, 0 and 1"),
        ({"fg": _labels(), "labellers": np.array([1, 2, 3])}, "3 labellers but 'fg' holds 2"),
        ({"other": np.zeros(3)}, "lacks key"),
    ],
)
def test_bad_labels_are_one_input_error_naming_the_file(tmp_path, content, problem):
    root = fake_root(tmp_path, ids=("1",))
    np.savez(root / "labels" / "1.npz", **content)
    with pytest.raises(InputError, match="1.npz") as err:
        load_bsds_fg(root, "1")
    assert problem in str(err.value)


def test_a_dataset_folder_without_labels_says_so(tmp_path):
    from snn_fg import datasets

    root = fake_root(tmp_path)
    shutil.rmtree(root / "labels")
    with pytest.raises(datasets.DatasetError, match=r"has no labels/ folder"):
        datasets.require("bsds-fg", root=tmp_path)
    shutil.rmtree(root)
    with pytest.raises(datasets.DatasetError, match="which is not in"):
        datasets.require("bsds-fg", root=tmp_path)
