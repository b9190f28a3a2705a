"""MapsSeriesWriter: per-window results of a recording, stacked where every
window has the same shape, ragged where the size changes (spike counts per
instantiated cell), zeros where a window lacks a map."""
import numpy as np
import pytest

from snn_fg.maps import Maps, MapsSeriesWriter, window_part


def _maps(value, **extra):
    z = np.full((3, 4), value, np.float32)
    return Maps(z, z + 1, z + 2, {"model": "spiking", "counts": {"cells": int(value)}}, extra)


def test_stacked_ragged_and_missing_arrays(tmp_path):
    windows = [
        _maps(1, spikes_S=np.array([1, 2, 3], np.int32), names=np.array(["a", "b"]), frame=np.ones((3, 4), np.uint8)),
        _maps(2),   # an empty window: no spike data at all
        _maps(3, spikes_S=np.array([7], np.int32), names=np.array(["a", "b"]), frame=np.full((3, 4), 5, np.uint8)),
    ]
    with MapsSeriesWriter(tmp_path / "maps.npz") as sink:
        for m in windows:
            sink.append(m)
        st = sink.stacked()
        sink.finish(extra_key=np.arange(3))
    assert st["fg_x"].shape == (3, 3, 4) and np.all(st["fg_x"][2] == 3)
    np.testing.assert_array_equal(st["spikes_S_offsets"], [0, 3, 3, 4])
    np.testing.assert_array_equal(window_part(st, "spikes_S", 0), [1, 2, 3])
    assert window_part(st, "spikes_S", 1).size == 0
    np.testing.assert_array_equal(window_part(st, "spikes_S", 2), [7])
    assert st["frame"].shape == (3, 3, 4) and not st["frame"][1].any() and np.all(st["frame"][2] == 5)
    back = Maps.load(tmp_path / "maps.npz")
    np.testing.assert_array_equal(window_part(back.extra, "spikes_S", 2), [7])
    np.testing.assert_array_equal(window_part(back.extra, "names", 2), ["a", "b"])
    # what differs from the first window's parameters is kept per window
    assert [w.get("counts") for w in back.params["windows"]] == [None, {"cells": 2}, {"cells": 3}]
    assert not list(tmp_path.glob(".maps.npz.*"))     # temporary parts removed


def test_trailing_shape_change_is_an_error(tmp_path):
    with MapsSeriesWriter(tmp_path / "maps.npz") as sink:
        sink.append(_maps(1, x=np.zeros((2, 2))))
        sink.append(_maps(1, x=np.zeros((2, 3))))
        with pytest.raises(ValueError, match="'x' changes its trailing shape"):
            sink.stacked()
