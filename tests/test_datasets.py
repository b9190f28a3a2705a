"""snn_fg.datasets: where data lives, and fetching verified by checksum from a local HTTP server.

The server runs in a thread and serves fixture files made here; one path
promises more bytes than it sends and closes the connection mid-body.
"""

import hashlib
import http.server
import io
import tarfile
import threading

import numpy as np
import pytest

from snn_fg import datasets
from snn_fg.cli import main
from snn_fg.datasets import convert
from snn_fg.datasets.catalogue import DataFile, Dataset
from snn_fg.datasets.transfer import DatasetError, arrays_sha256, download, npz_sha256

GOOD = b"event bytes " * 50_000  # 600 kB: several read chunks
OTHER = b"something else entirely" * 10


class _Handler(http.server.BaseHTTPRequestHandler):
    files: dict = {}

    def do_GET(self):  # noqa: N802 - http.server's name
        if self.path == "/dropped":
            self.send_response(200)
            self.send_header("Content-Length", str(len(GOOD)))
            self.end_headers()
            self.wfile.write(GOOD[: len(GOOD) // 3])
            self.wfile.flush()
            self.connection.shutdown(2)  # the server goes away mid-body
            self.close_connection = True
            return
        body = self.files.get(self.path)
        if body is None:
            self.send_error(404)
            return
        self.send_response(200)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def server():
    """Base URL of a local server; ``_Handler.files`` maps paths to bodies."""
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
    thread = threading.Thread(target=srv.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{srv.server_port}"
    srv.shutdown()
    thread.join()


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


OTHER_SHA = _sha(OTHER)


@pytest.fixture
def fixture_set(server, monkeypatch, tmp_path):
    """A dataset ``fixture`` of two files served locally, the data folder ``tmp_path`` via $SNN_FG_DATA."""
    _Handler.files = {"/a.bin": GOOD, "/b.bin": OTHER, "/wrong.bin": OTHER}

    def make(path_b="/b.bin", sha_b=OTHER_SHA):
        files = (
            DataFile(path="a.bin", size=len(GOOD), digest="bytes", sha256=_sha(GOOD), url=server + "/a.bin"),
            DataFile(path="sub/b.bin", size=len(OTHER), digest="bytes", sha256=sha_b, url=server + path_b),
        )
        ds = Dataset(
            name="fixture",
            description="test",
            source=server,
            licence="none",
            download="1 MB",
            files=files,
            fetch=convert.fetch_direct,
        )
        monkeypatch.setitem(datasets.DATASETS, "fixture", ds)
        return ds

    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path))
    return make


def _files_under(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())


def test_each_dataset_names_the_sources_of_its_own_files():
    """``snn-fg data info events`` listed the davis dataset's file among its sources (five for four files)."""
    from snn_fg.datasets.catalogue import DATASETS, RECORDING_URLS

    events, davis = DATASETS["events"], DATASETS["davis"]
    assert events.source.count("https://") == len(events.files) == 4
    assert RECORDING_URLS["aedat_davis346_street.aedat4"] not in events.source
    assert RECORDING_URLS["aedat_davis346_street.aedat4"] in davis.source


def test_a_dataset_fetched_by_hand_names_its_files_where_a_pip_user_can_read_them(capsys):
    """bsds-fg is not downloaded for the user: its instructions pointed at a file in the source tree
    (snn_fg/datasets/checksums.txt), which a pip install does not show. They now name a command that
    lists the files, one path a line under the dataset's folder."""
    ds = datasets.get("bsds-fg")
    assert "checksums.txt" not in ds.unavailable
    assert "snn-fg data info bsds-fg --files" in ds.unavailable
    assert main(["data", "info", "bsds-fg", "--files"]) == 0
    listed = capsys.readouterr().out.split()
    assert listed == [f.path for f in ds.files] and len(listed) == 320
    assert sum(p.startswith("images/") for p in listed) == sum(p.startswith("labels/") for p in listed) == 160


def test_the_environment_variable_chooses_the_data_folder(tmp_path, monkeypatch):
    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path))
    assert datasets.data_root() == tmp_path
    assert datasets.find("events", "dvs.es") is None
    with pytest.raises(DatasetError, match="snn-fg data fetch events"):
        datasets.require("events", "dvs.es")
    monkeypatch.delenv(datasets.ENV_VAR)
    assert datasets.data_root() != tmp_path


def test_fetch_downloads_verifies_and_then_keeps_what_is_there(fixture_set, tmp_path, capsys):
    fixture_set()
    assert main(["data", "fetch", "fixture", "--no-progress"]) == 0
    assert (tmp_path / "fixture" / "a.bin").read_bytes() == GOOD
    assert (tmp_path / "fixture" / "sub" / "b.bin").read_bytes() == OTHER
    assert "2 files fetched" in capsys.readouterr().out
    assert datasets.verify("fixture") == []
    (tmp_path / "fixture" / "a.bin").write_bytes(b"damaged")  # only the damaged file is fetched again
    assert [f.path for f in datasets.fetch("fixture", progress=False)] == ["a.bin"]
    assert datasets.fetch("fixture", progress=False) == []


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("snn-fg: error: "), err
    return err[0]


def test_a_checksum_mismatch_ends_with_one_line_and_no_partial_file(fixture_set, tmp_path, capsys):
    fixture_set(sha_b=_sha(b"what the catalogue expects"))
    assert main(["data", "fetch", "fixture", "--no-progress"]) == 2
    line = _one_error_line(capsys)
    assert "/b.bin: checksum mismatch" in line and "nothing was written" in line
    assert _files_under(tmp_path / "fixture") == ["a.bin"]  # the good file stays, verified


def test_a_dropped_connection_ends_with_one_line_and_no_partial_file(fixture_set, tmp_path, capsys):
    fixture_set(path_b="/dropped", sha_b=_sha(GOOD))
    assert main(["data", "fetch", "fixture", "--no-progress"]) == 2
    line = _one_error_line(capsys)
    assert "/dropped" in line and f"of {len(GOOD):,} bytes" in line, line
    assert _files_under(tmp_path / "fixture") == ["a.bin"]


def test_a_missing_url_ends_with_one_line(fixture_set, tmp_path, capsys):
    fixture_set(path_b="/nowhere")
    assert main(["data", "fetch", "fixture", "--no-progress"]) == 2
    assert "HTTP 404" in _one_error_line(capsys)
    assert _files_under(tmp_path / "fixture") == ["a.bin"]


def test_a_dataset_without_fetch_says_how_to_get_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path))
    assert main(["data", "fetch", "bsds-fg"]) == 2
    line = _one_error_line(capsys)
    assert "fetch not available" in line and convert.BSDS300_IMAGES_URL in line
    assert main(["data", "list"]) == 0
    out = capsys.readouterr().out
    assert f"data folder: {tmp_path}" in out and out.count("absent") == len(datasets.DATASETS)


def test_download_refuses_a_server_that_is_not_there(tmp_path):
    with pytest.raises(DatasetError, match="download failed after 0 bytes"):
        download("http://127.0.0.1:9/x", tmp_path / "x", sha256=None, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_arrays_checksum_ignores_the_container_and_sees_dtype_shape_and_values(tmp_path):
    a = {"x": np.arange(6, dtype=np.float32).reshape(2, 3), "m": np.array([1, 0], np.uint8)}
    np.savez(tmp_path / "plain.npz", **a)
    np.savez_compressed(tmp_path / "packed.npz", **a)
    ref = arrays_sha256(a)
    assert npz_sha256(tmp_path / "plain.npz") == npz_sha256(tmp_path / "packed.npz") == ref
    assert arrays_sha256({**a, "x": a["x"].astype(np.float64)}) != ref
    assert arrays_sha256({**a, "x": a["x"].reshape(3, 2)}) != ref
    assert arrays_sha256({**a, "m": np.array([1, 1], np.uint8)}) != ref


def _authors_csvs(image_id, rng):
    """Matrices as the authors' CSV files hold them, by file name; and the arrays they must become."""
    shape = (3, 4)
    csv = {name: rng.random(shape) for name, _ in convert.EDFG_ARRAYS.values()}
    csv["img_pos"] = (csv["img_pos"] > 0.5).astype(float)
    csv["img_neg"] = (csv["img_neg"] > 0.5).astype(float)
    resp = [rng.random(shape) for _ in range(convert.EDFG_DIRECTIONS)]
    csv.update({f"resp{22.5 * k:.1f}": r for k, r in enumerate(resp)})
    files = {}
    for name, m in csv.items():
        buf = io.BytesIO()
        np.savetxt(buf, m)
        files[f"/data/{image_id}/{name}_test.csv"] = buf.getvalue()
    want = {key: csv[name].astype(dtype) for key, (name, dtype) in convert.EDFG_ARRAYS.items()}
    want["resp"] = np.stack(resp, axis=-1).astype(np.float32)
    return files, want


def _jpeg_archive(members: dict) -> bytes:
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tar:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return buf.getvalue()


def test_the_authors_csvs_become_the_reference_npz_and_the_image_comes_from_the_archive(server, monkeypatch, tmp_path):
    files, want = _authors_csvs("7", np.random.default_rng(0))
    jpeg = b"\xff\xd8 a jpeg \xff\xd9"
    files["/BSDS300-images.tgz"] = _jpeg_archive(
        {"BSDS300/images/test/7.jpg": jpeg, "BSDS300/images/train/8.jpg": b"other"}
    )
    _Handler.files = files
    monkeypatch.setattr(convert, "EDFG_CSV_URL", server + "/data/{id}/{name}_test.csv")
    monkeypatch.setattr(convert, "BSDS300_IMAGES_URL", server + "/BSDS300-images.tgz")
    npz = DataFile(path="7.npz", size=0, digest="arrays", sha256=arrays_sha256(want))
    jpg = DataFile(path="images/7.jpg", size=len(jpeg), digest="bytes", sha256=_sha(jpeg))
    convert.fetch_bsds_edfg(tmp_path, [npz, jpg], progress=False)
    with np.load(tmp_path / "7.npz") as z:
        assert sorted(z.files) == sorted(want)
        for key, value in want.items():
            assert z[key].dtype == value.dtype and np.array_equal(z[key], value), key
    assert (tmp_path / "images" / "7.jpg").read_bytes() == jpeg

    wrong = DataFile(path="images/8.jpg", size=1, digest="bytes", sha256=_sha(b"not other"))
    with pytest.raises(DatasetError, match="8.jpg differs from the reference"):
        convert.fetch_bsds_edfg(tmp_path, [wrong], progress=False)
    bad = DataFile(path="7.npz", size=0, digest="arrays", sha256=_sha(b"x"))
    (tmp_path / "7.npz").unlink()
    with pytest.raises(DatasetError, match="converted arrays differ"):
        convert.fetch_bsds_edfg(tmp_path, [bad], progress=False)
    assert _files_under(tmp_path) == ["images/7.jpg"]


@pytest.mark.parametrize("name", sorted(datasets.DATASETS))
def test_the_reference_copies_match_the_catalogue(dataset, name):
    dataset(name)  # (each dataset skips alone when absent: the others are still checked)
    assert datasets.verify(name) == [], name


def test_data_list_says_why_every_dataset_is_absent_when_its_folder_is(tmp_path, monkeypatch, capsys):
    """$SNN_FG_DATA naming a folder that does not exist listed every dataset absent, and no more."""
    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path / "nowhere"))
    assert main(["data", "list"]) == 0
    assert f"({tmp_path / 'nowhere'} does not exist: snn-fg data fetch NAME makes it" in capsys.readouterr().out
    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path))
    assert main(["data", "list"]) == 0
    assert "does not exist" not in capsys.readouterr().out
