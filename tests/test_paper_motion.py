"""``--motion paper``: the authors' BSDS conversion (two 2-px copies through JPEG, ESIM).

The synthetic checks follow the published protocol only. The comparison with
the authors' six stored frames measures how close it comes: every stored
event pixel should be one of ours and carry our polarity; the acceptance
target (IoU >= 0.8) is out of reach with the published steps (see
experiments/README.md), so that test pins the measured level instead of
pretending to meet it.
"""

import numpy as np
import pytest

from snn_fg.events import image_to_frame
from snn_fg.events.paper_motion import imageio_uint8, paper_frames, shifted_copy

BSDS_IDS = ("12003", "35070", "105053", "159091", "22090", "41004")


def test_shifted_copy_moves_content_and_blackens_the_last_row():
    rgb = np.arange(6 * 5 * 3, dtype=np.uint8).reshape(6, 5, 3)
    down = shifted_copy(rgb, axis=0)
    assert np.array_equal(down[2:5], rgb[0:3])  # moved 2 rows down
    assert np.array_equal(down[:2], rgb[:2])  # uncovered rows keep the original ones
    assert not down[-1].any()  # the script leaves the last row black
    right = shifted_copy(rgb, axis=1)
    assert np.array_equal(right[:, 2:4], rgb[:, 0:2]) and not right[:, -1].any()


def test_imageio_stretch_maps_min_and_max_to_0_and_255():
    v = np.array([[0.0, 100.0], [50.0, 200.0]])
    assert imageio_uint8(v).tolist() == [[0, 127], [64, 255]]  # 127.5 rounds down (+0.499999999)


def test_a_vertical_edge_moved_right_gives_one_polarity_band():
    img = np.full((40, 40), 0.2)
    img[:, 20:] = 0.8  # dark left, light right
    pos, neg = image_to_frame(img, threshold=0.10, motion="paper")
    rows = slice(5, 30)
    # frame 0 (moved down) keeps the edge at column 20; frame 1 (moved right) brings the dark side over
    # columns 20-21: light -> dark, OFF. The last column goes black (OFF), the bottom row comes back (ON).
    assert np.flatnonzero((pos | neg)[rows].any(axis=0)).tolist() == [20, 21, 39]
    assert neg[rows, 20:22].all() and not pos[rows].any()
    assert neg[rows, -1].all() and pos[-1, :-1].all()
    frames = paper_frames(img)
    assert frames.shape == (2, 40, 40) and 0 <= frames.min() and frames.max() <= 1


@pytest.mark.parametrize("image_id", BSDS_IDS)
def test_paper_motion_against_the_authors_frames(dataset, image_id):
    ref = np.load(dataset("bsds-edfg", f"{image_id}.npz"))
    pos, neg = image_to_frame(dataset("bsds-edfg", "images", f"{image_id}.jpg"), threshold=0.10, motion="paper")
    ours, theirs = (pos | neg) > 0, (ref["pos"] | ref["neg"]) > 0
    both = ours & theirs
    recall = both.sum() / theirs.sum()
    iou = both.sum() / (ours | theirs).sum()
    agree = ((pos > 0) & (ref["pos"] > 0) | (neg > 0) & (ref["neg"] > 0))[both].mean()
    assert agree >= 0.98  # measured 0.988-1.000
    assert recall >= 0.98  # measured 0.984-0.996: their event pixels are a subset of ours
    # measured IoU 0.09-0.27: the authors kept only part of the pixels the protocol gives
    # (experiments/README.md, "--motion paper"); the shift4 conversion gives 0.15 on 12003
    assert 0.05 <= iou < 0.8


@pytest.mark.slow
def test_cli_motion_paper_is_recorded_and_refused_where_no_image_becomes_events(tmp_path, capsys):
    import json

    from snn_fg.cli import main
    from snn_fg.results.maps import Maps

    assert main(["run", "demo", "--motion", "paper", "--out", str(tmp_path / "a"), "--no-progress"]) == 0
    assert json.loads(json.dumps(Maps.load(tmp_path / "a" / "maps.npz").params))["source"]["motion"] == "paper"
    frame = tmp_path / "f.npz"
    pos, neg = image_to_frame(np.pad(np.full((20, 20), 0.8), 22, constant_values=0.2), motion="paper")
    np.savez(frame, pos=pos, neg=neg)
    assert main(["run", str(frame), "--motion", "paper", "--out", str(tmp_path / "b"), "--no-progress"]) == 2
    assert main(["run", "demo", "--model", "fbfg", "--motion", "paper", "--out", str(tmp_path / "c")]) == 2
    assert capsys.readouterr().err.count("--motion") == 2
    assert not (tmp_path / "b").exists() and not (tmp_path / "c").exists()
