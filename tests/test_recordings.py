"""The rate model on a real recording (dvs.es of the dataset ``events``: a toy biplane)."""

import numpy as np

from snn_fg.cli import main
from snn_fg.results.maps import Maps
from snn_fg.scoring.metrics import grouping_peak
from snn_fg.scoring.outline import filled_outline, inward_score


def test_biplane_windows(dataset, tmp_path):
    rec = dataset("events", "dvs.es")
    out = tmp_path / "out"
    assert (
        main(
            [
                "run",
                str(rec),
                "--out",
                str(out),
                "--model",
                "rate",
                "--window-ms",
                "85",
                "--start-ms",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    m = Maps.load(out / "maps.zarr")
    n = m.fg_x.shape[0]
    # 1.0 s recording, first ms dropped: windows start every 85 ms until the last event.
    assert n == 12 and m.fg_x.shape[1:] == (240, 320)
    assert np.all(np.diff(m.extra["t_start_us"]) == 85_000)
    from snn_fg.events import iter_windows

    inward = []
    for w, fx, fy, g in zip(iter_windows(rec, window_ms=85, start_ms=1), m.fg_x, m.fg_y, m.grouping):
        plane = filled_outline(w.pos | w.neg)
        r, c = grouping_peak(g)
        assert plane[r, c], f"window {w.index}: grouping peak ({r}, {c}) is off the plane"
        frac, count = inward_score(fx, fy, plane)
        assert count > 200
        inward.append(frac)
    assert np.median(inward) > 0.6
    assert np.mean(np.array(inward) > 0.5) >= 0.75
