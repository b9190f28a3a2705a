"""Fetchers that build a dataset's files from public originals, verified on the way.

* :func:`fetch_direct` - files published as they are (the sample recordings).
* :func:`fetch_bsds_edfg` - the authors' reference outputs: their per-image CSV
  files (``Berkleyresults/data/<id>/``, one matrix each, written by
  ``numpy.savetxt``) become one ``.npz`` per image with the arrays cast to
  the dtypes below, and each BSDS300 colour image is taken from the BSDS300
  archive as it is. Every product is checked against the reference checksum
  (the arrays' :func:`~snn_fg.datasets.transfer.arrays_sha256` for an
  ``.npz``) before it is moved into place.

A fetcher takes ``(folder, files, progress)``: the dataset's folder and the
:class:`~snn_fg.datasets.catalogue.DataFile` entries still to make.
"""

from __future__ import annotations

import hashlib
import re
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from snn_fg.datasets.transfer import DatasetError, arrays_sha256, download
from snn_fg.results.atomic import atomic_path

#: the authors' repository at the commit that last changed its BSDS outputs
EDFG_COMMIT = "b6eef865dcbaac5f94c785b00b0b21d232c3373e"
EDFG_CSV_URL = (
    "https://raw.githubusercontent.com/event-driven-robotics/figure-ground-organisation/"
    f"{EDFG_COMMIT}/Berkleyresults/data/{{id}}/{{name}}_test.csv"
)
#: the BSDS300 images (200 train + 100 test, ``BSDS300/images/{train,test}/<id>.jpg``), 22 MB
BSDS300_IMAGES_URL = "https://www2.eecs.berkeley.edu/Research/Projects/CS/vision/bsds/BSDS300-images.tgz"
#: the authors' oriented responses: one CSV per direction, 0, 22.5, ..., 337.5 degrees
EDFG_DIRECTIONS = 16
#: npz key -> (the authors' CSV name, dtype stored)
EDFG_ARRAYS = {
    "pos": ("img_pos", np.uint8),
    "neg": ("img_neg", np.uint8),
    "edges": ("frame", np.float32),
    "orientation": ("oriens", np.float32),
    "fg_x": ("X", np.float32),
    "fg_y": ("Y", np.float32),
    "grouping": ("grouping", np.float32),
}


def fetch_direct(folder: Path, files, progress: bool) -> None:
    """Download each file from its own URL, checked against its SHA-256."""
    for f in files:
        download(f.url, folder / f.path, sha256=f.sha256, progress=progress)


def _csv_matrix(url: str, path: Path) -> np.ndarray:
    try:
        return np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise DatasetError(f"{url}: not a matrix of numbers ({exc})") from None


def edfg_arrays(image_id: str, workdir: Path, progress: bool) -> dict[str, np.ndarray]:
    """Download the authors' CSVs of one image into ``workdir``; the ``.npz`` arrays."""

    def matrix(name):
        url = EDFG_CSV_URL.format(id=image_id, name=name)
        return _csv_matrix(url, download(url, workdir / f"{name}.csv", sha256=None, progress=progress))

    arrays = {key: matrix(name).astype(dtype) for key, (name, dtype) in EDFG_ARRAYS.items()}
    resp = [matrix(f"resp{k * 360 / EDFG_DIRECTIONS:.1f}") for k in range(EDFG_DIRECTIONS)]
    shapes = {a.shape for a in arrays.values()} | {r.shape for r in resp}
    if len(shapes) != 1:
        raise DatasetError(
            f"{EDFG_CSV_URL.format(id=image_id, name='*')}: the CSV files differ in shape ({sorted(shapes)})"
        )
    arrays["resp"] = np.stack(resp, axis=-1).astype(np.float32)
    return arrays


def _save_checked_npz(folder: Path, file, arrays, source: str) -> None:
    got = arrays_sha256(arrays)
    if got != file.sha256:
        raise DatasetError(
            f"{source}: the converted arrays differ from the reference {file.path} "
            f"(sha256 {got[:16]}..., expected {file.sha256[:16]}...); nothing was written"
        )
    with atomic_path(folder / file.path) as tmp:
        np.savez_compressed(tmp, **arrays)


def _bsds300_member(tar: tarfile.TarFile, image_id: str) -> bytes:
    want = re.compile(rf"(^|/)BSDS300/images/(train|test)/{image_id}\.jpg$")
    for member in tar.getmembers():
        if member.isfile() and want.search(member.name):
            return tar.extractfile(member).read()
    raise DatasetError(f"{BSDS300_IMAGES_URL}: the archive holds no image {image_id}")


def extract_bsds300_images(archive: Path, folder: Path, files) -> None:
    """Copy the BSDS300 images ``files`` (``.../<id>.jpg``) out of the archive, each checked by SHA-256."""
    try:
        with tarfile.open(archive) as tar:
            found = [(f, _bsds300_member(tar, Path(f.path).stem)) for f in files]
    except (tarfile.TarError, EOFError) as exc:
        raise DatasetError(f"{BSDS300_IMAGES_URL}: not a readable tar archive ({exc})") from None
    for f, data in found:
        got = hashlib.sha256(data).hexdigest()
        if got != f.sha256:
            raise DatasetError(
                f"{BSDS300_IMAGES_URL}: {Path(f.path).name} differs from the reference "
                f"(sha256 {got[:16]}..., expected {f.sha256[:16]}...); nothing was written"
            )
        with atomic_path(folder / f.path) as tmp:
            tmp.write_bytes(data)


def fetch_bsds_edfg(folder: Path, files, progress: bool) -> None:
    """The authors' reference outputs (from their CSVs) and the BSDS300 images they were made from."""
    frames = [f for f in files if f.path.endswith(".npz")]
    images = [f for f in files if f.path.endswith(".jpg")]
    with tempfile.TemporaryDirectory(prefix="snn-fg-data-") as tmp:
        for f in frames:
            image_id = Path(f.path).stem
            with tempfile.TemporaryDirectory(dir=tmp) as work:
                arrays = edfg_arrays(image_id, Path(work), progress)
            _save_checked_npz(folder, f, arrays, EDFG_CSV_URL.format(id=image_id, name="*"))
        if images:
            archive = download(BSDS300_IMAGES_URL, Path(tmp) / "BSDS300-images.tgz", sha256=None, progress=progress)
            extract_bsds300_images(archive, folder, images)
