"""What each dataset is: its files with their checksums, source, licence and how to fetch it.

The checksums (``checksums.txt`` beside this module) were taken from the
project's reference copies; a fetched or converted file must equal them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from importlib import resources

from snn_fg.datasets.convert import BSDS300_IMAGES_URL, EDFG_COMMIT, fetch_bsds_edfg, fetch_direct

_RAW = "https://raw.githubusercontent.com"
#: where each sample recording is published: a file of its package's test data, at a fixed commit
RECORDING_URLS = {
    "dvs.es": f"{_RAW}/neuromorphic-paris/event_stream/cc64e09f9c9650955fac94195c71ac27b6e2509f/examples/dvs.es",
    "tonic_sample_person.aedat4": f"{_RAW}/neuromorphs/tonic/40306d1b759b9fcca3dca2136a9b63ba05ba0e69/"
    "test/test_data/sample.aedat4",
    "tonic_sample_nmnist.bin": f"{_RAW}/neuromorphs/tonic/1b263825786c75ca576ed738977bfffd550f6358/"
    "test/test_data/sample_nmnist.bin",
    "expelliarmus_evt2_spinner.raw": f"{_RAW}/open-neuromorphic/expelliarmus/9ec30714e3e70fab080ae290c084605e9f42a838/"
    "tests/sample-files/evt2_sample.raw",
    "aedat_davis346_street.aedat4": f"{_RAW}/neuromorphicsystems/aedat/6570e5d2a5cbaa304f4a7c95f5e7f2c86133ce76/"
    "test_data.aedat4",
}
FG_LABELS_URL = "https://www2.eecs.berkeley.edu/Research/Projects/CS/vision/grouping/fg/fgdata.tar.gz"


@dataclass(frozen=True, kw_only=True)
class DataFile:
    """One file of a dataset.

    ``path`` is relative to the dataset's folder; ``size`` the bytes of the
    reference copy; ``digest`` says what ``sha256`` covers: ``"bytes"`` (the
    file) or ``"arrays"`` (an ``.npz``'s arrays); ``url`` where the file is
    published as it is, if it is.
    """

    path: str
    size: int
    digest: str
    sha256: str
    url: str | None = None


@dataclass(frozen=True, kw_only=True)
class Dataset:
    """A dataset: a folder of files under the data folder, named ``name``.

    ``fetch(folder, files, progress)`` makes the given files from the public
    source; ``None`` when no fetch is offered, and then ``unavailable`` says
    how to obtain the data by hand.
    """

    name: str
    description: str
    source: str
    licence: str
    download: str
    files: tuple[DataFile, ...]
    fetch: Callable | None = None
    unavailable: str = ""

    @property
    def size(self) -> int:
        """Bytes of the reference copy."""
        return sum(f.size for f in self.files)


@cache
def _checksums() -> dict[str, list[DataFile]]:
    by_dataset: dict[str, list[DataFile]] = {}
    text = resources.files("snn_fg.datasets").joinpath("checksums.txt").read_text()
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        rel, size, digest, sha = line.split()
        dataset, path = rel.split("/", 1)
        by_dataset.setdefault(dataset, []).append(
            DataFile(path=path, size=int(size), digest=digest, sha256=sha, url=RECORDING_URLS.get(path))
        )
    return by_dataset


def _catalogue() -> dict[str, Dataset]:
    files = _checksums()
    sets = [
        Dataset(
            name="events",
            files=tuple(files["events"]),
            fetch=fetch_direct,
            download="5.5 MB",
            description="four real event-camera recordings: dvs.es (a toy biplane, ATIS, 1 s), a person "
            "(DVXplorer, AEDAT4), a spinning dot (Prophesee EVT2), an N-MNIST digit",
            # (its own files' sources: the davis dataset's file is listed there, not here)
            source="test data of the packages that read these formats: "
            + ", ".join(f.url for f in files["events"] if f.url),
            licence="the packages' licences: event_stream and tonic GPL-3.0, expelliarmus GPL-2.0",
        ),
        Dataset(
            name="davis",
            files=tuple(files["davis"]),
            fetch=fetch_direct,
            download="6.1 MB",
            description="a DAVIS346 recording with its grey-level (APS) frames: a street seen from a "
            "still camera, cars passing, 2.4 s, 78,830 events and 59 frames (25 per second) on one clock",
            source="test data of the aedat package (its sdist on PyPI holds the same file as "
            "tests/data/test_data.aedat4): " + RECORDING_URLS["aedat_davis346_street.aedat4"],
            licence="the aedat package's: MIT",
        ),
        Dataset(
            name="bsds-edfg",
            files=tuple(files["bsds-edfg"]),
            fetch=fetch_bsds_edfg,
            download="555 MB (the authors' CSV files, 89 MB per image, and the 22 MB BSDS300 archive)",
            description="six BSDS images as the authors' event frames with their rate model's outputs "
            "(the rate reference), and the colour images they were made from",
            source="github.com/event-driven-robotics/figure-ground-organisation at "
            f"{EDFG_COMMIT[:7]}, Berkleyresults/data/<id>/*.csv (converted to one .npz per image); "
            f"images from {BSDS300_IMAGES_URL}",
            licence="the authors' repository states no licence (published with D'Angelo et al. 2025); "
            "BSDS300 images for non-commercial research and education",
        ),
        Dataset(
            name="bsds-fg",
            files=tuple(files["bsds-fg"]),
            download="not offered",
            description="160 BSDS300 images with the two human figure/ground labellings of Fowlkes, Martin "
            "& Malik (2007), the ground truth of the paper's Table 1 and Fig. 6",
            source=f"labels {FG_LABELS_URL}, images {BSDS300_IMAGES_URL}",
            licence="BSDS300 and its figure/ground labels: non-commercial research and education",
            unavailable=f"download {FG_LABELS_URL} and {BSDS300_IMAGES_URL}; for each image id that "
            "'snn-fg data info bsds-fg --files' lists, copy images/<id>.jpg and write labels/<id>.npz with "
            "fg: int8 (2, H, W), the first matrix of each of the two labellers' .fg files "
            "(MATLAB readbin) unchanged, and labellers: int32 (2,) their ids (no converter is "
            "offered: it could not be checked against the reference here)",
        ),
    ]
    return {d.name: d for d in sets}


DATASETS: dict[str, Dataset] = _catalogue()
