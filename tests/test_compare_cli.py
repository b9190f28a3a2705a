"""``snn-fg compare`` and the times a user sees: files only when asked, a
figure of both maps and their difference, times from the recording's first event."""

import json
import os

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.results.maps import Maps

#: a recording stamped in Unix time, as AEDAT4 files are (2020-05-11, in us)
UNIX_T0 = 1_589_163_147_368_900


@pytest.fixture(scope="module")
def unix_recording(tmp_path_factory):
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(16).image, motion="circle")
    ev = rec.events.copy()
    ev["t"] += UNIX_T0 - ev["t"][0]
    path = tmp_path_factory.mktemp("rec") / "disc.npz"
    save_events(path, ev, rec.sensor_size)
    return path


def _run(path, out, *more):
    assert (
        main(["run", str(path), "--out", str(out), "--window-ms", "50", "--levels", "4", "--no-progress", *more]) == 0
    )
    return Maps.load(out / "maps.zarr")


@pytest.mark.slow
def test_times_count_from_the_first_event_in_maps_figures_and_params(unix_recording, tmp_path, monkeypatch):
    from snn_fg.models import Model

    titles = []
    real = Model.write_figures
    monkeypatch.setattr(
        Model,
        "write_figures",
        lambda self, out, maps, inputs, crop=None, **kw: (
            titles.append(kw["titles"]) or real(self, out, maps, inputs, crop=crop, **kw)
        ),
    )
    m = _run(unix_recording, tmp_path / "a", "--start-ms", "100", "--max-windows", "3")
    assert titles == [
        ["window 0: 100-150 ms", "window 1: 150-200 ms", "window 2: 200-250 ms"]
    ]  # not "0-50 ms" (from the first window)
    assert m.extra["t_start_us"].tolist() == [100_000, 150_000, 200_000]
    assert m.extra["t_end_us"].tolist() == [150_000, 200_000, 250_000]
    assert m.params["source"]["first_event_us"] == UNIX_T0 and m.params["source"]["start_ms"] == 100


@pytest.mark.slow
def test_compare_writes_nothing_unless_asked_and_shows_relative_times(unix_recording, tmp_path, capsys):
    _run(unix_recording, tmp_path / "a", "--max-windows", "3")
    _run(unix_recording, tmp_path / "b", "--max-windows", "3", "--r0", "6")
    before = {d: sorted(os.listdir(tmp_path / d)) for d in ("a", "b")}
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b" / "maps.zarr")]) == 0
    out = capsys.readouterr().out
    assert (
        {d: sorted(os.listdir(tmp_path / d)) for d in ("a", "b")}
        == before
        == {d: ["maps.png", "maps.zarr", "timeline.png", "windows.csv"] for d in ("a", "b")}
    )
    assert sorted(os.listdir(tmp_path)) == ["a", "b"] and "saved" not in out
    lines = out.splitlines()
    assert lines[0].startswith("snn-fg: note: A and B were made with other model parameters (r0 8.0 against 6.0)")
    t_column = [line.split()[2] for line in lines[2:5]]
    assert t_column == ["0.0", "50.0", "100.0"] and str(UNIX_T0 // 1000)[:6] not in out
    assert (
        main(
            [
                "compare",
                str(tmp_path / "a"),
                str(tmp_path / "b" / "maps.zarr"),
                "--json",
                str(tmp_path / "c.json"),
                "--plot",
                str(tmp_path / "c.png"),
            ]
        )
        == 0
    )
    record = json.loads((tmp_path / "c.json").read_text())
    rows = record["windows"]
    assert [r["t_start_ms"] for r in rows] == [0.0, 50.0, 100.0]
    # (the pooled figures the printed verdict gives, and what chose the pixels: a table made from the file alone)
    pooled, n = record["all_windows"], sum(r["pixels_compared"] for r in rows)
    assert pooled["pixels_compared"] == n > 0 and record["options"]["outline_px"] is None
    within = sum(r["pixels_compared"] * r["angle_within_45_frac"] for r in rows) / n
    assert abs(pooled["angle_within_45_frac"] - within) < 1e-12 and f"{within:.1%} of {n:,} pixels" in pooled["verdict"]
    assert (
        pooled["verdict"] in " ".join(capsys.readouterr().out.split()) and record["snn_fg_version"]
    )  # (as printed, wrapped)
    assert (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG"


def test_the_compare_figure_names_each_side_by_its_run_folder(tmp_path, monkeypatch):
    import snn_fg.scoring.compare_figure as figures

    spiking = {"model": "spiking", "network": {"origin": "recipe", "recipe": "compact"}, "backend": {"name": "fast"}}
    for name, params in (("run-a", spiking), ("run-b", {"model": "rate", "input_pool": 3})):
        z = np.zeros((4, 5), np.float32)
        (tmp_path / "out" / name).mkdir(parents=True)
        Maps(z, z, z, params).save(tmp_path / "out" / name / "maps.npz")
    seen, described = [], []

    def save(path, a, b, rows, names, **kw):
        seen.append(names)
        described.append(kw["described"])

    monkeypatch.setattr(figures, "save_compare_figure", save)
    for b in ("run-b", "run-b/maps.npz"):
        assert (
            main(
                [
                    "compare",
                    str(tmp_path / "out" / "run-a"),
                    str(tmp_path / "out" / b),
                    "--plot",
                    str(tmp_path / "c.png"),
                ]
            )
            == 0
        )
    assert seen == [("A (run-a)", "B (run-b)")] * 2
    # the title says which model made each (until 30 Nov the figure named the folders only)
    assert described[0] == [
        "A: run-a, the spiking model on the compact network (fast backend)",
        "B: run-b, the rate model, its input pooled in 3 x 3 blocks",
    ]


def test_the_compare_figure_draws_both_maps_and_their_angle_difference():
    from snn_fg.scoring.compare_figure import compare_figure
    from snn_fg.scoring.metrics import compare_maps

    fx = np.zeros((3, 30, 40), np.float32)
    fx[:, 10, 5:35] = 1.0  # an edge owned by the side to its right...
    fy = np.zeros_like(fx)
    bx = fx.copy()
    bx[1, 10, 5:15] = -1.0  # ...in B's window 1 partly by the other side
    bx[1, 20, 5:10] = 1.0  # and five vectors A has not
    starts = {"t_start_us": np.array([0, 50_000, 100_000])}
    a, b = Maps(fx, fy, fx.copy(), {}, starts), Maps(bx, fy, fx.copy(), {}, starts)
    rows = compare_maps(a, b)
    fig = compare_figure(a, b, rows, max_rows=2)
    axes = np.array(fig.axes[:6]).reshape(2, 3)
    assert "2 of 3 compared windows shown" in fig._suptitle.get_text()
    assert [ax.get_title() for ax in axes[:, 0]] == ["A window 0, 0 ms", "A window 2, 100 ms"]
    fig = compare_figure(a, b, rows[1:2])
    ax_a, ax_b, ax_d = fig.axes[:3]
    grey, diff = (im.get_array() for im in ax_d.images)
    diff = np.ma.filled(diff.astype(float), np.nan)
    assert np.all(diff[10, 5:15] == 180) and np.all(diff[10, 15:35] == 0)
    assert np.isnan(diff[20, 5:10]).all() and np.all(grey[20, 5:10] < 1)  # one map only: grey
    assert np.isnan(diff).sum() == diff.size - 30
    assert "mean 60°, 67% within 45°" in ax_d.get_title()


def test_outline_compares_the_vectors_on_the_event_regions_outline_only(tmp_path, capsys):
    """Two maps that agree on a filled disc's outline and disagree inside it
    (a recording whose object fills with events): on every pixel they look
    unrelated, within 2 px of the outline they are the same, and the
    grouping columns do not change."""
    from snn_fg.scoring.metrics import compare_maps
    from snn_fg.scoring.outline import event_outlines, outline_band

    yy, xx = np.mgrid[:32, :32]
    region = np.hypot(yy - 16, xx - 16) < 10
    band = outline_band(region, 2)
    inward_x, inward_y = (16 - xx) * region, (yy - 16) * region  # y up
    rng = np.random.default_rng(0)
    a = [np.where(band, v, rng.normal(size=v.shape) * region) for v in (inward_x, inward_y)]
    b = [np.where(band, v, rng.normal(size=v.shape) * region) for v in (inward_x, inward_y)]
    g = region.astype(float)
    ma = Maps(*a, g, extra={"event_frame": region.astype(np.int8)})
    mb = Maps(*b, g)
    (whole,) = compare_maps(ma, mb)
    (outline,) = compare_maps(ma, mb, where=event_outlines(ma, mb, 2))
    assert whole["angle_diff_mean_deg"] > 40 and whole["pixels_compared"] == region.sum()
    assert outline["pixels_compared"] == band.sum() < region.sum() / 2
    assert outline["angle_diff_mean_deg"] == 0.0 and outline["angle_within_45_frac"] == 1.0
    assert outline["grouping_pearson_r"] == whole["grouping_pearson_r"]

    ma.save(tmp_path / "a.npz"), mb.save(tmp_path / "b.npz")
    assert main(["compare", str(tmp_path / "a.npz"), str(tmp_path / "b.npz"), "--outline", "2"]) == 0
    assert "within 2 px of the event region's outline" in " ".join(capsys.readouterr().out.split())
    mb.save(tmp_path / "c.npz")
    assert main(["compare", str(tmp_path / "b.npz"), str(tmp_path / "c.npz"), "--outline", "2"]) == 2
    err = capsys.readouterr().err
    assert "--outline 2 (outline_px=2 in Python) needs the event frame a recording" in err and "still image" in err


def test_with_outline_the_compare_figure_draws_the_difference_where_it_was_taken():
    """The figure of ``compare --outline`` shows the angle difference on the
    outline band only, as its numbers were taken, and says so."""
    from snn_fg.scoring.compare_figure import compare_figure
    from snn_fg.scoring.metrics import compare_maps
    from snn_fg.scoring.outline import event_outlines, outline_band

    yy, xx = np.mgrid[:32, :32]
    region = np.hypot(yy - 16, xx - 16) < 10
    band = outline_band(region, 2)
    a = Maps(region * 1.0, region * 0.0, region * 1.0, extra={"event_frame": region.astype(np.int8)})
    b = Maps(np.where(band, 1.0, -1.0) * region, region * 0.0, region * 1.0)
    where = event_outlines(a, b, 2)
    rows = compare_maps(a, b, where=where)
    ax_d = compare_figure(a, b, rows, where=where).axes[2]
    grey, diff = (np.ma.filled(im.get_array().astype(float), np.nan) for im in ax_d.images)
    assert np.all(diff[band] == 0) and np.isnan(diff[~band]).all()  # the inside's 180 deg left out
    assert np.all(grey[region & ~band] < 1) and "on the compared pixels" in ax_d.get_title()
    whole = compare_figure(a, b, compare_maps(a, b)).axes[2]
    assert np.nanmax(np.ma.filled(whole.images[1].get_array().astype(float), np.nan)) == 180


def test_a_map_without_any_vector_is_named_under_the_table():
    """A window where one map has no vector compares nothing (nan in the
    rows, "-" in the table's angle columns, never "nan"); the table says which map is empty, in which windows."""
    from snn_fg.cli.compare_maps import compare_table
    from snn_fg.scoring.metrics import compare_maps

    fx = np.zeros((2, 20, 20), np.float32)
    fx[:, 5, 5:15] = 1.0
    empty = fx.copy()
    empty[1] = 0.0
    starts = {"t_start_us": np.array([0, 85_000])}
    rows = compare_maps(Maps(fx, fx * 0, fx, {}, starts), Maps(empty, fx * 0, fx, {}, starts))
    text = compare_table(rows)
    assert rows[1]["pixels_b"] == 0 and np.isnan(rows[1]["angle_diff_mean_deg"])
    assert text.splitlines()[-1] == (
        "B has no figure-ground vector in 1 of 2 compared windows (1): nothing to compare there (-)"
    )
    assert "nan" not in text and text.splitlines()[2].split()[4:7] == ["-", "-", "-"]  # (cover, mean, <=45)
    assert "has no figure-ground vector" not in compare_table(rows[:1])


def test_compare_says_when_its_two_models_part_on_a_recording():
    """The spiking network on a recording's events against the rate model gets a note pointing at why
    they part there; a still frame's spiking maps, or two rate runs, do not."""
    from snn_fg.cli.compare_maps import expectations

    z = np.zeros((4, 4), np.float32)

    def maps(model, mode=None):
        params = {"model": model, **({"simulation": {"mode": mode}} if mode else {})}
        return Maps(z, z, z, params, {})

    events, still, rate = maps("spiking", "continuous"), maps("spiking", "frame"), maps("rate")
    for a, b in ((events, rate), (rate, events)):
        (note,) = expectations(a, b)
        assert "part there" in note and "docs/validation.md" in note and "--write-frame" in note
    unnamed = Maps(z, z, z, {}, {})  # (maps that do not say their model)
    assert expectations(still, rate) == expectations(rate, rate) == expectations(events, events) == []
    assert expectations(unnamed, unnamed) == expectations(unnamed, events) == []


def test_compare_help_promises_in_its_table_only_what_the_table_prints(capsys):
    """The help said the table gives the angle difference's median and MSE; they are in --json only."""
    from snn_fg.cli.compare_maps import _COLUMNS

    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    printed = " ".join(key for _, key, *_ in _COLUMNS)
    for metric in ("median", "MSE"):
        assert metric.lower() not in printed.lower()
        at = text.index(metric)
        assert "(--json also keeps" in text[max(0, at - 60) : at]


def test_a_window_beyond_a_recording_is_refused_by_the_options_name(tmp_path, capsys):
    """--window past a recording's windows: one line naming the option and the file's windows (it
    said "window=7 is not among the 3 windows of a map", compare_maps' keyword)."""
    z = np.zeros((3, 4, 5), np.float32)
    for name in ("a", "b"):
        Maps(z, z, z, {"model": "rate"}).save(tmp_path / f"{name}.npz")
    assert main(["compare", str(tmp_path / "a.npz"), str(tmp_path / "b.npz"), "--window", "7"]) == 2
    err = capsys.readouterr().err
    assert "--window 7" in err and "holds windows 0 to 2" in err and "window=" not in err
    # one check, compare_maps': its error carries the map and its windows, which the line above says
    from snn_fg.scoring.metrics import compare_maps
    from snn_fg.scoring.pairing import WindowOutOfRange

    one = Maps(z[0], z[0], z[0], {})
    with pytest.raises(WindowOutOfRange) as got:
        compare_maps(one, Maps.load(tmp_path / "b.npz"), window=7)
    assert (got.value.window, got.value.side, got.value.n) == (7, "b", 3)
    assert "window=7 is not among the 3 windows of b (0 to 2)" in str(got.value)


def test_runs_made_one_at_a_time_are_paired_by_image_and_pooled(tmp_path, capsys):
    """A user who ran each image to its own --out folder gets one pooled table: A's runs, then as many
    of B's, paired by input image in any order. Image x: A equals B (0°); image y: A opposite to B
    (180°), with as many vectors: pooled, half within 45°, mean 90°. Runs that do not pair up: one line."""
    fx = np.zeros((20, 20), np.float32)
    fx[5, 5:15] = 1.0
    z = np.zeros_like(fx)

    def save(name, image, sign, model):
        params = {"model": model, "source": {"input": f"/data/{image}.jpg", "kind": "image"}}
        Maps(sign * fx, z, z, params).save(tmp_path / name / "maps.npz")
        return str(tmp_path / name)

    a = [save("spk_x", "x", 1.0, "spiking"), save("spk_y", "y", -1.0, "spiking")]
    b = [save("rate_y", "y", 1.0, "rate"), save("rate_x", "x", 1.0, "rate")]  # (another order)
    out = tmp_path / "pooled.json"
    assert main(["compare", *a, *b, "--no-baseline", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["A", "B", "image"]
    assert [ln.split()[2] for ln in lines[1:3]] == ["x", "y"]
    assert (
        "All images: A within 45° of B on 50.0% of 20 pixels, which are 100% of B's vectors; "
        "mean absolute difference 90.0°" in " ".join(text.split())
    )
    assert (
        "A: 2 runs (spk_x, spk_y), the spiking model" in text and "B: 2 runs (rate_x, rate_y), the rate model" in text
    )
    record = json.loads(out.read_text())
    assert record["all_windows"]["angle_within_45_frac"] == 0.5
    assert record["all_windows"]["angle_diff_mean_deg"] == pytest.approx(90.0)
    assert [(p["image"], os.path.basename(p["b"])) for p in record["pairs"]] == [("x", "rate_x"), ("y", "rate_y")]

    for folder, runs in (("spk", a), ("rate", b)):  # (two folders of runs, snn-fg run on several images each)
        rows = "".join(f"{os.path.basename(r)}.jpg,{r},done,1,1.0,\n" for r in runs)
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "summary.csv").write_text("recording,output,status,windows,seconds,error\n" + rows)
    assert main(["compare", str(tmp_path / "spk"), str(tmp_path / "rate"), "--no-baseline"]) == 0
    assert "50.0% of 20 pixels, which are 100% of B's vectors; mean absolute difference 90.0°" in " ".join(
        capsys.readouterr().out.split()
    )

    other = save("rate_z", "z", 1.0, "rate")
    for given, said in (
        ([*a, b[0]], "3 runs given: pooled runs are as many of A's model as of B's"),
        ([*a, b[0], other], f"snn-fg: error: {a[0]}: A's run of image x has no B run of that image"),
        ([a[0], a[0], *b], f"snn-fg: error: {a[0]}: is a second A run of image x (also {a[0]})"),
    ):
        assert main(["compare", *given, "--no-baseline", "--json", str(tmp_path / "no.json")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], err
        assert not (tmp_path / "no.json").exists()


def test_min_confidence_on_two_maps_without_confidence_is_refused(tmp_path, capsys):
    """compare RATE_A RATE_B --min-confidence 2 ran, applied nothing, and recorded the threshold in --json."""
    fx = np.zeros((8, 8), np.float32)
    fx[4, 1:7] = 1.0
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        Maps(fx, 0 * fx, fx.copy(), params={"model": "rate"}).save(tmp_path / name / "maps.npz")
    argv = ["compare", str(tmp_path / "a"), str(tmp_path / "b"), "--no-baseline"]
    assert main([*argv, "--min-confidence", "2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--min-confidence: neither" in err and "holds fg_confidence" in err
    assert main(argv) == 0
