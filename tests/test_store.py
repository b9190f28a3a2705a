"""The store a recording's maps grow in (snn_fg.results.store): stacked, ragged and
missing per-window arrays, read back by Maps.load and by zarr-python (an
independent Zarr reader), only complete windows visible, continued after a
window cut short."""

import json
import threading

import numpy as np
import pytest

from snn_fg.errors import InputError
from snn_fg.results.atomic import write_bytes
from snn_fg.results.maps import Maps, window_part
from snn_fg.results.store import FLAT_CHUNK, MapsStore, read_attrs


def _maps(value, **extra):
    z = np.full((3, 4), value, np.float32)
    return Maps(z, z + 1, z + 2, {"model": "spiking", "counts": {"cells": int(value)}}, extra)


WINDOWS = [
    lambda: _maps(
        1, spikes_S=np.array([1, 2, 3], np.int32), names=np.array(["a", "b"]), frame=np.ones((3, 4), np.uint8)
    ),
    lambda: _maps(2),  # an empty window: no spike data at all
    lambda: _maps(3, spikes_S=np.array([7], np.int32), names=np.array(["a", "b"]), frame=np.full((3, 4), 5, np.uint8)),
]


def _write(path, windows, flush=True):
    """A store of ``windows``, flushed at the end (``flush``) as a run that stops is."""
    store = MapsStore.create(path, {"input": "x"})
    for i, m in enumerate(windows):
        store.append(m(), t_start_us=np.int64(10 * i))
    if flush:
        store.flush()
    return store


def test_stacked_ragged_and_missing_arrays_read_back_by_us_and_by_zarr(tmp_path):
    zarr = pytest.importorskip("zarr", reason="zarr-python is in the test extra: pip install -e '.[test]'")
    path = tmp_path / "maps.zarr"
    _write(path, WINDOWS).finish({"model": "spiking", "final": True})
    back = Maps.load(path)
    assert back.fg_x.shape == (3, 3, 4) and np.all(back.fg_x[2] == 3) and np.all(back.grouping[1] == 4)
    np.testing.assert_array_equal(back.extra["spikes_S_offsets"], [0, 3, 3, 4])
    np.testing.assert_array_equal(window_part(back.extra, "spikes_S", 0), [1, 2, 3])
    assert window_part(back.extra, "spikes_S", 1).size == 0
    np.testing.assert_array_equal(window_part(back.extra, "names", 2), ["a", "b"])
    assert not back.extra["frame"][1].any() and np.all(back.extra["frame"][2] == 5)  # absent: zeros
    assert back.params["final"] is True
    # what differs from the first window's parameters is kept per window
    assert [w.get("counts") for w in back.params["windows"]] == [None, {"cells": 2}, {"cells": 3}]
    g = zarr.open_group(str(path), mode="r")
    assert g.attrs["snn_fg"]["windows_complete"] == 3 and g.attrs["snn_fg"]["complete"] is True
    for key in ("fg_x", "grouping", "frame", "spikes_S", "spikes_S_offsets", "names", "t_start_us"):
        np.testing.assert_array_equal(g[key][:], back.extra.get(key, getattr(back, key, None)))
    assert g["window_params"][1] == '{"counts": {"cells": 2}}'


def test_arrays_made_ahead_from_a_template_store_the_same_windows(tmp_path):
    """A live run makes its store's arrays from its warm-up's last window before the first window
    comes (MapsStore.prepare): nothing is appended (no window, no row), and the windows that follow
    read back as from a store that made each array at its first window, the ragged ones' offsets and
    the zeros of an array a window lacks included."""
    plain = _write(tmp_path / "plain.zarr", WINDOWS)
    ahead = MapsStore.create(tmp_path / "ahead.zarr", {"input": "x"})
    ahead.prepare(_maps(9, spikes_S=np.array([5], np.int32), frame=np.ones((3, 4), np.uint8)), t_start_us=np.int64(0))
    assert ahead.n == 0 and {a.n for k, a in ahead.arrays.items() if not k.endswith("_offsets")} == {0}
    for i, m in enumerate(WINDOWS):
        ahead.append(m(), t_start_us=np.int64(10 * i))
    ahead.flush()
    a, b = Maps.load(tmp_path / "ahead.zarr"), Maps.load(plain.path)
    assert sorted(a.extra) == sorted(b.extra) and a.params == b.params
    for key in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    for key in b.extra:
        np.testing.assert_array_equal(a.extra[key], b.extra[key])


def test_flat_arrays_span_chunks(tmp_path):
    """A ragged array longer than one chunk, filled across chunk edges."""
    path = tmp_path / "maps.zarr"
    parts = [np.arange(n, dtype=np.int64) + 1000 * n for n in (FLAT_CHUNK - 3, 5, 2 * FLAT_CHUNK + 1)]
    _write(path, [lambda p=p: _maps(0, spikes_S=p) for p in parts])
    back = Maps.load(path)
    for i, p in enumerate(parts):
        np.testing.assert_array_equal(window_part(back.extra, "spikes_S", i), p)


def test_per_window_scalars_span_chunks(tmp_path, monkeypatch):
    from snn_fg.results import store as st

    monkeypatch.setattr(st, "SCALAR_CHUNK", 4)
    path = tmp_path / "maps.zarr"
    _write(path, [lambda i=i: _maps(i) for i in range(10)]).finish({})
    assert sorted(p.name for p in (path / "t_start_us").iterdir()) == [".zarray", "0", "1", "2"]
    back = Maps.load(path)
    np.testing.assert_array_equal(back.extra["t_start_us"], 10 * np.arange(10))
    zarr = pytest.importorskip("zarr", reason="zarr-python is in the test extra: pip install -e '.[test]'")
    np.testing.assert_array_equal(zarr.open_group(str(path), mode="r")["t_start_us"][:], 10 * np.arange(10))


def test_during_a_run_readers_see_whole_windows_up_to_a_second_late_and_all_at_the_end(tmp_path, monkeypatch):
    """The store is flushed (chunks holding complete windows, shapes,
    windows_complete) at the first window, then at most once a second
    (FLUSH_EVERY_S), and at the end: between, every reader, Zarr's and
    snn-fg's, sees a prefix of whole windows."""
    zarr = pytest.importorskip("zarr", reason="zarr-python is in the test extra: pip install -e '.[test]'")
    from snn_fg.results import store as st
    from snn_fg.results import zarr_array

    path = tmp_path / "maps.zarr"
    now = [0.0]
    monkeypatch.setattr(st.time, "monotonic", lambda: now[0])
    replaced = []
    for module in (zarr_array, st):  # (the store's own files, and those its writing thread replaces)
        monkeypatch.setattr(module, "write_bytes", lambda p, data: replaced.append(p.name) or write_bytes(p, data))
    store = _write(path, [lambda: _maps(0)], flush=False)
    store.writer.wait()
    n_first = len(replaced)
    for i in range(1, 4):  # (within the second: no file replaced, the attributes and shapes wait for the flush)
        store.append(_maps(i), t_start_us=np.int64(10 * i))
    assert len(replaced) == n_first
    for reader in (zarr.open_group(str(path), mode="r")["fg_x"], Maps.load(path).fg_x):
        assert reader.shape[0] == 1  # flushed at the first window only
    assert read_attrs(path)["snn_fg"]["windows_complete"] == 1
    now[0] = st.FLUSH_EVERY_S
    store.append(_maps(4), t_start_us=np.int64(40))
    store.writer.wait()  # (the flush's files are replaced on the store's writing thread)
    g = zarr.open_group(str(path), mode="r")
    assert g["fg_x"].shape[0] == g["t_start_us"].shape[0] == 5 and np.all(g["fg_x"][4] == 4)
    np.testing.assert_array_equal(g["t_start_us"][:], 10 * np.arange(5))
    assert Maps.load(path).fg_x.shape[0] == 5 and ".zattrs" in replaced[n_first:]
    store.append(_maps(5), t_start_us=np.int64(50))  # (under a second later)
    store.writer.wait()
    assert zarr.open_group(str(path), mode="r")["fg_x"].shape[0] == Maps.load(path).fg_x.shape[0] == 5
    store.finish({"model": "spiking"})
    g = zarr.open_group(str(path), mode="r")
    np.testing.assert_array_equal(g["t_start_us"][:], 10 * np.arange(6))
    assert g["fg_x"].shape[0] == g["window_params"].shape[0] == 6
    assert g["fg_x"].metadata.compressor.codec_id == "zstd"


def test_a_flush_while_the_run_writes_does_not_wait_for_the_disk_and_keeps_its_order(tmp_path, monkeypatch):
    """Replacing a file waits for the disk (ext4 writes the new file's data
    first: about 4 ms each, 18 files a flush of a live run's store). The
    flush a run makes once a second returns while its files are still being
    written, on the store's writing thread, in order: chunks, shapes, then
    the attributes that make the windows visible; readers see the earlier
    windows meanwhile, and the run's end waits for every file."""
    from snn_fg.results import store as st

    path = tmp_path / "maps.zarr"
    now = [0.0]
    monkeypatch.setattr(st.time, "monotonic", lambda: now[0])
    gate, order = threading.Event(), []

    def slow_disk(p, data):
        gate.wait(timeout=30)
        order.append(p.name)
        write_bytes(p, data)

    store = _write(path, [lambda: _maps(0)], flush=False)
    store.writer.wait()
    monkeypatch.setattr(st, "write_bytes", slow_disk)
    for i in range(1, 5):
        now[0] = i * st.FLUSH_EVERY_S
        store.append(_maps(i), t_start_us=np.int64(10 * i))  # (each a flush: returns with the disk held)
    assert not order and read_attrs(path)["snn_fg"]["windows_complete"] == 1
    assert Maps.load(path).fg_x.shape[0] == 1
    gate.set()
    store.finish({})
    assert read_attrs(path)["snn_fg"]["windows_complete"] == 5 and Maps.load(path).fg_x.shape[0] == 5
    # each flush: every array's chunk holding complete windows, then its shape; the attributes last
    flushes = " ".join(order).split(".zattrs")
    assert len(flushes) == 6 and flushes[-1] == ""  # (4 while writing, the end's, and nothing after)
    for names in flushes[:4]:
        names = names.split()
        assert "0" in names and all(names[i + 1] == ".zarray" for i, n in enumerate(names) if n == "0")


def test_a_disk_error_on_the_writing_thread_is_raised_in_the_run(tmp_path, monkeypatch):
    from snn_fg.results import store as st

    path = tmp_path / "maps.zarr"
    store = _write(path, [lambda: _maps(0)], flush=False)
    store.writer.wait()

    def full_disk(p, data):
        raise OSError(28, "No space left on device", str(p))

    monkeypatch.setattr(st, "write_bytes", full_disk)
    store.append(_maps(1), t_start_us=np.int64(10))
    with pytest.raises(OSError, match="No space left"):
        store.flush()
    assert read_attrs(path)["snn_fg"]["windows_complete"] == 1  # (the store as it was before the error)


def test_a_store_written_with_zlib_reads_and_resumes_in_zlib(tmp_path, monkeypatch):
    """Stores written before the chunks were zstd (zlib): read as they are,
    and a resumed run adds its windows in the array's own codec."""
    zarr = pytest.importorskip("zarr", reason="zarr-python is in the test extra: pip install -e '.[test]'")
    from snn_fg.results import zarr_array

    path = tmp_path / "maps.zarr"
    monkeypatch.setattr(zarr_array, "COMPRESSOR", {"id": "zlib", "level": 1})
    _write(path, [lambda i=i: _maps(i) for i in range(3)])
    monkeypatch.undo()
    assert json.loads((path / "fg_x" / ".zarray").read_text())["compressor"]["id"] == "zlib"
    store = MapsStore.reopen(path, {"input": "x"})
    store.append(_maps(3), t_start_us=np.int64(30))
    store.finish({})
    for name in ("fg_x", "t_start_us"):
        assert json.loads((path / name / ".zarray").read_text())["compressor"]["id"] == "zlib"
    back = Maps.load(path)
    assert [float(back.fg_x[i][0, 0]) for i in range(4)] == [0, 1, 2, 3]
    np.testing.assert_array_equal(zarr.open_group(str(path), mode="r")["t_start_us"][:], 10 * np.arange(4))


def test_a_failed_write_leaves_the_file_as_it_was_and_no_part(tmp_path):
    target = tmp_path / "chunk"
    write_bytes(target, b"first")
    with pytest.raises(TypeError):
        write_bytes(target, "not bytes")
    assert target.read_bytes() == b"first" and [p.name for p in tmp_path.iterdir()] == ["chunk"]


def test_a_reader_sees_complete_windows_only_and_a_cut_window_is_written_again(tmp_path, monkeypatch):
    from snn_fg.results import store as st

    path = tmp_path / "maps.zarr"
    _write(path, WINDOWS[:2])
    real = st.GrowingArray.append

    def cut(self, values):
        if self.path.name == "grouping":  # the window is cut short after its fg_x and fg_y
            raise KeyboardInterrupt
        real(self, values)

    monkeypatch.setattr(st.GrowingArray, "append", cut)
    with pytest.raises(KeyboardInterrupt):
        MapsStore.reopen(path, {"input": "x"}).append(_maps(9))
    monkeypatch.setattr(st.GrowingArray, "append", real)
    seen = Maps.load(path)
    assert seen.fg_x.shape[0] == 2 and not read_attrs(path)["snn_fg"]["complete"]
    store = MapsStore.reopen(path, {"input": "x"})
    assert store.n == 2
    store.append(WINDOWS[2](), t_start_us=np.int64(20))
    store.flush()
    whole = tmp_path / "whole.zarr"
    _write(whole, WINDOWS)
    a, b = Maps.load(path), Maps.load(whole)
    assert a.fg_x.shape[0] == 3
    for key in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    for key in b.extra:
        np.testing.assert_array_equal(a.extra[key], b.extra[key])


def test_another_run_and_a_changing_shape_are_refused(tmp_path):
    path = tmp_path / "maps.zarr"
    store = _write(path, WINDOWS[:1])
    with pytest.raises(ValueError, match="'frame' changes its shape between windows"):
        store.append(_maps(1, frame=np.zeros((2, 3))))
    with pytest.raises(InputError, match=r"these differ: input \(x before, y now\)$"):
        MapsStore.reopen(path, {"input": "y"})
    with pytest.raises(
        InputError,
        match=r"these differ: input \(x before, not given now\), maps_grid \(not given before, blocks now\)$",
    ):
        MapsStore.reopen(path, {"maps_grid": "blocks"})
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="holds no maps.npz or maps.zarr"):
        Maps.load(tmp_path / "empty")
    (tmp_path / "empty" / ".zattrs").write_text("{}")  # (a Zarr group of another program)
    with pytest.raises(InputError, match="not a maps store written by snn-fg"):
        Maps.load(tmp_path / "empty")


def test_maps_come_from_the_package_and_print_as_one_short_line(tmp_path):
    import snn_fg

    path = tmp_path / "maps.zarr"
    _write(
        path,
        [
            lambda i=i: _maps(i, **{f"spikes_{k}": np.arange(k + 1, dtype=np.int32) for k in range(40)})
            for i in range(3)
        ],
    )
    m = snn_fg.Maps.load(path)
    assert snn_fg.Maps is Maps
    text = repr(m)
    assert "\n" not in text and len(text) < 300
    assert text.startswith("Maps(3 windows of 4 x 3, model 'spiking'") and "spikes_0" in text
    assert str(m) == text


def test_a_growing_array_keeps_its_chunk_until_full_or_flushed_and_reads_back_the_same(tmp_path):
    """Chunks of several rows: a full chunk is written once (in place before any flush
    wrote it, atomically after), the chunk being filled at a flush (its rows past the
    length as fill values, though its buffer held an earlier chunk's rows); every
    row reads back as appended, by us and by zarr-python."""
    from snn_fg.results.zarr_array import GrowingArray, ZarrArray

    a = GrowingArray.create(tmp_path / "a", np.float32, (2, 3), 4)
    replaced = []
    a.replace = lambda p, data: replaced.append(p.name) or write_bytes(p, data)
    rows = np.arange(14 * 6, dtype=np.float32).reshape(14, 2, 3) + 1
    for i in range(9):  # (chunks 0 and 1 full and written in place, chunk 2 holds row 8)
        a.append(rows[i : i + 1])
    assert replaced == [] and sorted(p.name for p in a.path.glob("[0-9]*")) == ["0.0.0", "1.0.0"]
    a.flush()  # (chunk 2 on disk: row 8, then fill values, not chunk 0's rows its buffer held)
    assert replaced == ["2.0.0"]
    np.testing.assert_array_equal(a.chunk(2)[1:], 0)
    a.append(rows[9:12])  # (chunk 2 full: a flush wrote it, so it is replaced)
    assert replaced == ["2.0.0", "2.0.0"]
    a.append(rows[12:14])
    a.flush()
    a.write_shape()
    np.testing.assert_array_equal(np.asarray(ZarrArray(a.path)), rows)
    zarr = pytest.importorskip("zarr", reason="zarr-python is in the test extra: pip install -e '.[test]'")
    np.testing.assert_array_equal(zarr.open_array(str(a.path), mode="r")[:], rows)


def test_a_damaged_store_is_refused_in_one_line_not_read_as_zeros(tmp_path, monkeypatch):
    """A chunk deleted from a copied run read as zeros, and ``snn-fg compare`` printed a normal
    table made from them (a new user's trial, 30 Nov); an array deleted whole ended in a traceback."""
    import shutil

    monkeypatch.setattr("snn_fg.results.store.WINDOW_CHUNK", 1)  # (one window a chunk: the second's alone)
    path = tmp_path / "maps.zarr"
    _write(path, WINDOWS).finish({"model": "spiking"})
    whole = tmp_path / "whole.zarr"
    shutil.copytree(path, whole)
    (path / "fg_y" / "1.0.0").unlink()
    with pytest.raises(InputError, match=r"fg_y/1\.0\.0: missing: windows 1-1 of the 3 the store holds complete"):
        Maps.load(path)
    shutil.rmtree(whole / "grouping")
    with pytest.raises(InputError, match="has no grouping array: the store is incomplete or damaged"):
        Maps.load(whole)
    # an array first met at a later window has no chunks for the windows before it: not damage
    late = tmp_path / "late.zarr"
    _write(late, [lambda: _maps(1), lambda: _maps(2), lambda: _maps(3, frame=np.ones((3, 4), np.uint8))]).finish({})
    assert not (late / "frame" / "0.0.0").exists()
    back = Maps.load(late)
    assert not back.extra["frame"][0].any() and back.extra["frame"][2].all()


def test_a_folder_with_no_maps_says_so_not_that_it_lacks_a_zattrs(tmp_path):
    """An empty folder, or a still run's with its maps.npz deleted, was 'not a maps store: no .zattrs'."""
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "maps.png").write_bytes(b"a figure")
    with pytest.raises(InputError, match="holds no maps.npz or maps.zarr: not a finished run's folder"):
        Maps.load(tmp_path / "run")
