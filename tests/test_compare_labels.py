"""``snn-fg compare RUN LABELS``: a run's maps against human figure/ground labels. On a disc with
hand-made labels the answer is known (vectors inward: side accuracy 1; half flipped: a half; a
quarter without vectors: coverage three quarters); on a BSDS image the numbers are Table 1's;
bad labels end in one line naming the file, nothing written."""

import json

import numpy as np
import pytest
from scipy import ndimage as ndi

from snn_fg.cli import main
from snn_fg.frames.scenes import disc
from snn_fg.results.maps import Maps
from snn_fg.scoring.groundtruth import boundary_directions

SIZE = 64


def _disc_labels():
    """A bsds-fg map of a radius-20 disc: +1 one pixel inside its outline, -1 one pixel outside."""
    inside = disc(20).labels > 0
    assert inside.shape == (SIZE, SIZE)
    fig = inside & ~ndi.binary_erosion(inside)
    ground = ~inside & ndi.binary_dilation(inside)
    return fig.astype(np.int8) - ground.astype(np.int8)


@pytest.fixture
def disc_case(tmp_path):
    """(labels folder, write(fg_x, fg_y) -> a run folder, the labelled directions) of the disc."""
    fg = _disc_labels()
    (tmp_path / "bsds" / "labels").mkdir(parents=True)
    np.savez(tmp_path / "bsds" / "labels" / "disc.npz", fg=np.stack([fg, fg]), labellers=np.array([7, 9]))
    truth = boundary_directions(fg)

    def write(fx, fy, name="run", **extra):
        params = {"model": "rate", "source": {"input": str(tmp_path / "disc.png"), "kind": "image"}}
        z = np.zeros((SIZE, SIZE), np.float32)
        Maps(fx.astype(np.float32), fy.astype(np.float32), z, params, extra).save(tmp_path / name / "maps.npz")
        return tmp_path / name

    return tmp_path / "bsds", write, truth


def _scores(capsys, *args) -> dict:
    """compare's --json rows, by (image, labeller)."""
    out = args[0].parent / "scores.json"
    assert main(["compare", *map(str, args), "--json", str(out), "--force"]) == 0
    capsys.readouterr()
    return {(r["image"], r["labeller"]): r for r in json.loads(out.read_text())["rows"]}


def test_known_answers_on_a_disc(disc_case, capsys):
    labels, write, (tx, ty, valid) = disc_case
    rows, cols = np.nonzero(valid)
    inward = _scores(capsys, write(tx, ty, "inward"), labels)
    both = inward[("disc", "both")]
    assert both["side_accuracy"] == 1.0 and both["within45"] == 1.0 and both["coverage"] == 1.0
    assert both["mean_abs_deg"] < 1e-6 and both["n_truth"] == 2 * valid.sum()

    left = np.zeros_like(valid)
    left[:, : SIZE // 2] = True  # the left half of the disc's outline points outwards
    flipped = _scores(capsys, write(np.where(left, -tx, tx), np.where(left, -ty, ty), "flipped"), labels)
    share_right = float(np.mean(cols >= SIZE // 2))
    for who in ("1 (id 7)", "2 (id 9)", "both"):
        s = flipped[("disc", who)]
        assert s["side_accuracy"] == pytest.approx(share_right) and abs(s["side_accuracy"] - 0.5) < 0.03
        assert s["coverage"] == 1.0 and s["mean_abs_deg"] == pytest.approx(180 * (1 - share_right))

    quarter = np.zeros_like(valid)
    quarter[: SIZE // 2, : SIZE // 2] = True  # no vector on the top-left quarter of the outline
    missing = _scores(capsys, write(np.where(quarter, 0, tx), np.where(quarter, 0, ty), "quarter"), labels)
    s = missing[("disc", "both")]
    assert s["coverage"] == pytest.approx(1 - np.mean(quarter[rows, cols])) and abs(s["coverage"] - 0.75) < 0.03
    assert s["side_accuracy"] == 1.0  # what has a vector is right: read the two together

    # a spiking run's vectors below --min-confidence count as none: the same quarter, by its confidence
    sure = write(tx, ty, "confidence", fg_confidence=np.where(quarter, 1.0, 3.0).astype(np.float32))
    out = sure.parent / "conf.json"
    assert main(["compare", str(sure), str(labels), "--min-confidence", "2", "--json", str(out)]) == 0
    capsys.readouterr()
    (row,) = [r for r in json.loads(out.read_text())["rows"] if r["labeller"] == "both"]
    assert row["coverage"] == s["coverage"] and row["side_accuracy"] == 1.0


def test_the_printed_table_says_what_each_number_is(disc_case, capsys, tmp_path):
    labels, write, (tx, ty, _) = disc_case
    run = write(tx, ty)
    assert main(["compare", str(run), str(labels / "labels" / "disc.npz"), "--plot", str(tmp_path / "f.png")]) == 0
    out = capsys.readouterr().out
    head = out.splitlines()[0].split()
    assert head == ["image", "labeller", "labelled", "cover", "side", "<=45°", "mean°", "signed°"]
    for words in ("side accuracy", "coverage", "mean signed difference", "the paper reports", "chance 0.5"):
        assert words in out.replace("\n", " ")
    assert (tmp_path / "f.png").read_bytes().startswith(b"\x89PNG")
    assert main(["compare", str(run), str(labels / "labels")]) == 0  # (the folder's labels/ itself)
    assert capsys.readouterr().out.splitlines()[3].split()[:2] == ["disc", "both"]


def test_a_folder_of_runs_is_scored_per_image_and_pooled(disc_case, capsys, tmp_path):
    labels, write, (tx, ty, valid) = disc_case
    write(tx, ty, "runs/a")
    left = np.zeros_like(valid)
    left[:, : SIZE // 2] = True
    write(np.where(left, -tx, tx), np.where(left, -ty, ty), "runs/b")
    (tmp_path / "runs" / "summary.csv").write_text(
        "recording,output,status,windows,seconds,error\n"
        f"disc.png,{tmp_path / 'runs' / 'a'},done,1,1.0,\n"
        f"disc.png,{tmp_path / 'runs' / 'b'},done,1,1.0,\n"
        "other.png,,failed,0,0.1,bad\n"
    )
    rows = _scores(capsys, tmp_path / "runs", labels)
    pooled = rows[("all 2", "both")]
    assert pooled["n_truth"] == 4 * valid.sum()
    assert pooled["side_accuracy"] == pytest.approx((1 + float(np.mean(np.nonzero(valid)[1] >= SIZE // 2))) / 2)
    assert main(["compare", str(tmp_path / "runs"), str(labels)]) == 0
    assert "1 failed run(s), not scored: other.png" in capsys.readouterr().out


@pytest.mark.parametrize(
    "case",
    [
        "size",
        "no_id",
        "garbage",
        "values",
        "recording_option",
        "other_image",
        "rate_confidence",
        "wrong_key",
        "figure_only",
    ],
)
def test_bad_labels_one_line_nothing_written(disc_case, capsys, tmp_path, case):
    labels, write, (tx, ty, _) = disc_case
    run = write(tx, ty)
    b = labels
    extra = []
    if case == "size":
        b = tmp_path / "small.npz"
        np.savez(b, fg=np.zeros((2, 32, 48), np.int8))
    elif case == "no_id":
        (labels / "labels" / "disc.npz").rename(labels / "labels" / "12003.npz")
    elif case == "garbage":
        b = labels / "labels" / "disc.npz"
        b.write_bytes(b"PK\x03\x04 not really a zip")
    elif case == "values":
        b = tmp_path / "two.npz"
        np.savez(b, fg=np.full((1, SIZE, SIZE), 2, np.int8))
    elif case == "other_image":  # (a new user scored 100080's run against 104022's labels: a note, exit 0)
        run = write(tx, ty, "bsds_run")
        params = Maps.load(run).params
        params["source"]["input"] = str(tmp_path / "100080.jpg")
        m = Maps.load(run)
        Maps(m.fg_x, m.fg_y, m.grouping, params, m.extra).save(run / "maps.npz")
        b = tmp_path / "104022.npz"
        np.savez(b, fg=np.stack([_disc_labels()]))
    elif case == "wrong_key":  # (labels saved under another name were called "not a maps file")
        b = tmp_path / "mine.npz"
        np.savez(b, foo=np.stack([_disc_labels()]))
    elif case == "figure_only":  # (only the +1 strip: every score was a dash, exit 0)
        b = tmp_path / "plus.npz"
        np.savez(b, fg=np.stack([np.maximum(_disc_labels(), 0)]))
    elif case == "rate_confidence":  # (--min-confidence on a rate run's maps was silently a no-op)
        extra = ["--min-confidence", "2"]
    else:
        extra = ["--window", "0"]
    out = tmp_path / "s.json"
    code = main(["compare", str(run), str(b), "--json", str(out), "--plot", str(tmp_path / "s.png"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and not out.exists() and not (tmp_path / "s.png").exists()
    named = {
        "size": ("small.npz", "32 x 48", "64 x 64"),
        "no_id": ("bsds", "disc", "no "),
        "garbage": ("disc.npz",),
        "values": ("two.npz", "-1, 0 and 1"),
        "recording_option": ("--window", "human labels"),
        "other_image": ("104022.npz", "image 104022", "image 100080"),
        "rate_confidence": ("--min-confidence", "no fg_confidence"),
        "wrong_key": ("mine.npz", "nor human labels (fg)", "found foo"),
        "figure_only": ("plus.npz", "give no direction", "no -1 pixel"),
    }[case]
    assert all(w in err[0] for w in named), err[0]


@pytest.mark.slow
def test_the_numbers_are_table1s_on_a_bsds_image(dataset, tmp_path, capsys):
    """The command on `snn-fg run IMAGE --motion paper` equals experiments/paper/table1.py's per-image
    row of that image (the rate model, threshold 0.10): the same scoring, one home."""
    from experiments.evaluation import ImageEvaluation, evaluate_image
    from experiments.paper.table1 import per_image_rows

    root = dataset("bsds-fg")
    image = root / "images" / "12003.jpg"
    assert main(["run", str(image), "--out", str(tmp_path / "run"), "--motion", "paper", "--no-figures"]) == 0
    got = _scores(capsys, tmp_path / "run", root)[("12003", "both")]
    settings = ImageEvaluation(thresholds=(0.10,), fbfg_operators=(), fig6=False)
    result = evaluate_image(root=str(root), image_id="12003", settings=settings)
    (row,) = per_image_rows({"12003": result})
    for key in ("side_accuracy", "coverage", "within45", "mean_abs_deg", "mean_signed_deg", "n_pixels", "n_truth"):
        assert got[key] == pytest.approx(row[key], rel=1e-9, abs=1e-9), key


def test_runs_made_one_at_a_time_are_scored_and_pooled_as_a_folder_of_runs_is(disc_case, capsys, tmp_path):
    """Each image run to its own --out folder, then RUN1 RUN2 LABELS: one table, each image and all of them
    pooled (side accuracy, coverage, within 45° and the mean absolute difference), as a batch's folder gives;
    one image given twice, or runs for one labels file, is one line."""
    labels, write, (tx, ty, valid) = disc_case
    np.savez(labels / "labels" / "disc2.npz", **np.load(labels / "labels" / "disc.npz"))
    inward = write(tx, ty, "one")
    left = np.zeros_like(valid)
    left[:, : SIZE // 2] = True
    half = write(np.where(left, -tx, tx), np.where(left, -ty, ty), "two")  # (of disc.png: a second run of it)
    m = Maps.load(half)  # (the same maps as a run of disc2.png, whose labels are disc's)
    Maps(m.fg_x, m.fg_y, m.grouping, {**m.params, "source": {**m.params["source"], "input": "disc2.png"}}).save(
        tmp_path / "two2" / "maps.npz"
    )
    rows = _scores(capsys, inward, tmp_path / "two2", labels)
    share_right = float(np.mean(np.nonzero(valid)[1] >= SIZE // 2))
    pooled = rows[("all 2", "both")]
    assert pooled["n_truth"] == 4 * valid.sum() and pooled["coverage"] == 1.0
    assert pooled["side_accuracy"] == pytest.approx((1 + share_right) / 2)
    assert pooled["mean_abs_deg"] == pytest.approx(180 * (1 - share_right) / 2)
    assert rows[("disc2", "both")]["side_accuracy"] == pytest.approx(share_right)
    assert main(["compare", str(inward), str(tmp_path / "two2"), str(labels)]) == 0
    said = capsys.readouterr().out
    assert f"runs: {inward}, {tmp_path / 'two2'} (2 images, the rate model)" in said
    for given, said in (
        ([inward, half], f"{half}: is a second run of image disc (also {inward}): give each once"),
        ([inward, tmp_path / "two2", labels / "labels" / "disc.npz"], "is one image's labels, but"),
    ):
        out = tmp_path / "no.json"
        labelled = [] if len(given) == 3 else [str(labels)]
        assert main(["compare", *map(str, given), *labelled, "--json", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], err
        assert not out.exists()


def test_the_table_says_what_it_scored_and_the_pooled_interval_the_experiment_pages_give(disc_case, capsys, tmp_path):
    """compare RUN LABELS names the model, network and settings read from the run, and under a table of
    several images the pooled scores with the pages' 95 % bootstrap interval over the images. Two images
    with as many labelled pixels, side accuracy 1 and s: resamples pool to 1, (1 + s) / 2 or s, a quarter
    of them each of the ends, so the interval is [s, 1] around (1 + s) / 2."""
    labels, write, (tx, ty, valid) = disc_case
    one = write(tx, ty, "inward", fg_confidence=np.ones_like(tx, np.float32))
    params = {
        **Maps.load(one).params,
        "model": "spiking",
        "levels": 4,
        "r0": 8.0,
        "network": {"origin": "recipe", "recipe": "compact"},
        "backend": {"name": "fast"},
    }
    m = Maps.load(one)
    Maps(m.fg_x, m.fg_y, m.grouping, params, m.extra).save(tmp_path / "spiking" / "maps.npz")
    assert main(["compare", str(tmp_path / "spiking"), str(labels)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "read: the spiking model on the compact network (fast backend); levels 4, r0 8" in lines
    assert any(ln.startswith("interval: none for one image") for ln in lines)

    left = np.zeros_like(valid)
    left[:, : SIZE // 2] = True
    write(np.where(left, -tx, tx), np.where(left, -ty, ty), "runs/b")
    write(tx, ty, "runs/a")
    (tmp_path / "runs" / "summary.csv").write_text(
        "recording,output,status,windows,seconds,error\n"
        f"disc.png,{tmp_path / 'runs' / 'a'},done,1,1.0,\n"
        f"disc.png,{tmp_path / 'runs' / 'b'},done,1,1.0,\n"
    )
    out = tmp_path / "scores.json"
    assert main(["compare", str(tmp_path / "runs"), str(labels), "--json", str(out)]) == 0
    said = capsys.readouterr().out
    s = float(np.mean(np.nonzero(valid)[1] >= SIZE // 2))
    assert "read: the rate model\n" in said  # (no network, no stage parameter stored in these maps)
    assert f"side {(1 + s) / 2:.3f} [{s:.3f}, 1.000]" in said and "95 % interval of 2000 bootstrap resamples" in said
    assert "cover 1.000 [1.000, 1.000]" in said
    record = json.loads(out.read_text())
    side = record["interval"]["side_accuracy"]
    assert (side["low"], side["high"]) == (pytest.approx(s), 1.0) and record["interval"]["resamples"] == 2000
    assert record["images"][0]["settings"] == "the rate model"


def test_the_labels_figure_draws_each_labelled_pixel_three_wide_with_its_own_value():
    """One-pixel boundaries could not be read at screen size in a 5306 px wide figure: each labelled
    pixel's value is drawn over its 3 x 3 neighbourhood (display only), and a labelled pixel keeps its own."""
    from snn_fg.scoring.labels_figure import _spread, _thick

    valid = np.zeros((7, 7), bool)
    valid[3, 3] = valid[3, 5] = True
    values = np.full((7, 7), np.nan)
    values[3, 3], values[3, 5] = 10.0, 170.0
    shown = _spread(values, _thick(valid), np.nan)
    assert np.isfinite(shown).sum() == 15  # (two 3 x 3 blocks sharing column 4: rows 2-4, columns 2-6)
    assert shown[3, 3] == 10.0 and shown[3, 5] == 170.0 and shown[2, 2] == 10.0 and shown[4, 6] == 170.0
    assert np.isnan(shown[0, 0]) and np.isnan(shown[3, 0])
    empty = np.zeros((4, 4), bool)
    assert np.array_equal(_spread(np.zeros((4, 4)), _thick(empty), 0.0), np.zeros((4, 4)))
