"""Recordings that read but look wrong, and what a decoder leaves out:
a file cut at an event boundary warns (and cannot be cut into windows), and
summaries name what they skip, with counts."""

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.errors import InputError
from snn_fg.events import EVENT_DTYPE, iter_windows, open_recording, save_events
from snn_fg.events.writers import encode_evt2, encode_evt3


def _burst_es(path):
    """A DVS Event Stream opening with 200 ON events at t = 0 (5 bytes each: no
    time passes between them), then events every 10 ms."""
    ev = np.zeros(300, EVENT_DTYPE)
    ev["x"], ev["y"] = np.arange(300) % 40, np.arange(300) // 40
    ev["t"][200:] = np.arange(1, 101) * 10_000
    ev["p"][:200] = 1
    save_events(path, ev, (40, 30))
    return path


def test_a_file_cut_at_an_event_boundary_warns_and_cannot_be_run(tmp_path, capsys, recwarn):
    from snn_fg.errors import InputWarning

    rec = open_recording(_burst_es(tmp_path / "whole.es"))  # the whole file: no warning, 12 windows
    assert len(rec) == 300 and not [w for w in recwarn if issubclass(w.category, InputWarning)]
    assert len(list(iter_windows(rec, window_ms=85))) == 12
    whole = (tmp_path / "whole.es").read_bytes()
    cut = tmp_path / "cut.es"
    cut.write_bytes(whole[: 20 + 5 * 100])  # header, then exactly 100 whole events of the burst
    problem = f"{cut}: all 100 events have the same timestamp (0 us), so the recording spans no time"
    assert main(["events", str(cut), "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert "events:     100 (ON 100.0 %)" in out
    assert err == f"snn-fg: warning: {problem}; is the file cut short?\n"
    assert main(["run", str(cut), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("snn-fg: error: " + problem) and err.count("\n") == 1 and not (tmp_path / "o").exists()
    with pytest.warns(InputWarning, match="all 100 events have the same timestamp"):
        open_recording(cut)
    with pytest.raises(InputError, match="spans no time and has no window to cut"):
        next(iter_windows(cut))
    cut.write_bytes(whole[: 20 + 5 * 100 + 2])  # (cut inside an event: an error with its byte offset)
    with pytest.raises(InputError, match="file ends inside an event .* byte offset 520"):
        open_recording(cut)


class _FakeAedat:
    """Stands in for ``aedat.Decoder`` on a DAVIS recording: events, APS
    frames, IMU samples, triggers and a second event stream."""

    def __init__(self, path):
        ev = np.zeros(5, [("t", "<i8"), ("x", "<u2"), ("y", "<u2"), ("on", "?")])
        ev["t"] = np.arange(5) * 1000
        later = ev.copy()
        later["t"] += 5000
        self.packets = [
            {"stream_id": 0, "events": ev},
            {"stream_id": 1, "frame": self.frame(2000)},
            {"stream_id": 2, "imus": np.zeros(7)},
            {"stream_id": 1, "frame": self.frame(6000)},
            {"stream_id": 3, "triggers": np.zeros(3)},
            {"stream_id": 4, "events": ev[:2]},
            {"stream_id": 0, "events": later},
        ]

    @staticmethod
    def frame(t):
        """A grey frame exposed from ``t - 250`` to ``t + 250`` us."""
        pixels = np.zeros((6, 8), np.uint8)
        exposure = {"exposure_begin_t": t - 250, "exposure_end_t": t + 250, "offset_x": 0, "offset_y": 0}
        return {"t": t, "format": "L", "width": 8, "height": 6, "pixels": pixels, **exposure}

    def id_to_stream(self):
        return {
            0: {"type": "events", "width": 8, "height": 6},
            1: {"type": "frame", "width": 8, "height": 6},
            2: {"type": "imus"},
            3: {"type": "triggers"},
            4: {"type": "events", "width": 8, "height": 6},
        }

    def __iter__(self):
        return iter(self.packets)


def test_summaries_name_what_they_skip(tmp_path, monkeypatch, capsys):
    import aedat

    path = tmp_path / "davis.aedat4"
    body = b"<dv><node name='outInfo'/></dv>"
    path.write_bytes(b"#!AER-DAT4.0\r\n" + len(body).to_bytes(4, "little") + body)
    monkeypatch.setattr(aedat, "Decoder", _FakeAedat)
    assert main(["events", str(path), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "events:     10 " in out
    assert "skipped:    7 IMU samples, 3 trigger events, 2 events of stream 4 (read, not used by the model)" in out
    assert "APS frames: 2 frames of 8 x 6, one every 4.0 ms (250.0 per second), 2 to 6 ms after the first event" in out

    ev = np.zeros(6, EVENT_DTYPE)
    ev["x"], ev["t"] = np.arange(6), np.arange(6) * 100
    trigger = (0xA << 28) | 5  # an EVT2 external trigger word
    raw = encode_evt2(ev, (8, 6))
    (tmp_path / "t.raw").write_bytes(raw + np.array([trigger, trigger], "<u4").tobytes())
    evt3 = encode_evt3(ev, (8, 6))
    (tmp_path / "t3.raw").write_bytes(evt3 + np.array([(0xA << 12) | 1], "<u2").tobytes())
    for name, n in (("t.raw", 2), ("t3.raw", 1)):
        assert main(["events", str(tmp_path / name), "--no-progress"]) == 0
        assert f"skipped:    {n} trigger events (read" in capsys.readouterr().out

    log = tmp_path / "data.log"
    right, imu = (1 << 22) | (3 << 1), (1 << 23) | 5
    log.write_text(f"0 1.0 AE (10 2 20 4 30 {right} 40 {imu})\n1 1.1 IMUS (1 2 3)\n2 1.2 AE (50 6)\n")
    assert main(["events", str(log), "--no-progress"]) == 0
    (skipped,) = [line for line in capsys.readouterr().out.splitlines() if line.startswith("skipped:")]
    listed = skipped.removeprefix("skipped:").removesuffix(" (read, not used by the model)").strip()
    assert sorted(listed.split(", ")) == [
        "1 IMUS bottles",
        "1 events of the other camera (channel 1)",
        "1 non-vision samples (IMU or skin)",
    ]


def _cut_es(tmp_path):
    """A 0.8 s recording (2 MB: read in several chunks) and the same cut inside its last event."""
    n = 400_000
    ev = np.zeros(n, EVENT_DTYPE)
    ev["x"], ev["y"], ev["p"] = np.arange(n) % 40, (np.arange(n) // 40) % 30, np.arange(n) % 2
    ev["t"] = np.arange(n) * 2  # nine 85 ms windows and a part
    save_events(tmp_path / "whole.es", ev, (40, 30))
    cut = tmp_path / "cut.es"
    cut.write_bytes((tmp_path / "whole.es").read_bytes()[:-3])
    return cut


def test_a_file_cut_inside_an_event_part_way_ends_the_run_at_the_windows_before_it(tmp_path, capsys):
    """A recording cut short inside an event: the run stops there with one line naming the
    byte offset and the event, and its output is the finished run of the windows complete
    before the cut, the same as --max-windows gives (never a half-written window)."""
    from snn_fg.results.maps import Maps

    cut = _cut_es(tmp_path)
    opts = ["--no-progress", "--no-figures"]
    assert main(["run", str(cut), "--out", str(tmp_path / "o"), *opts]) == 2
    err = [line for line in capsys.readouterr().err.strip().splitlines() if "warning" not in line]
    assert err == [
        f"snn-fg: error: {cut}: file ends inside an event (2 of 5 bytes) (at byte offset 2000015, event 399999); "
        f"stopped there: the 9 windows complete before it are written to {tmp_path / 'o'}/, a finished run "
        "(what --max-windows 9 gives)"
    ]
    assert main(["run", str(cut), "--out", str(tmp_path / "m"), *opts, "--max-windows", "9"]) == 0
    cut_short, limited = Maps.load(tmp_path / "o"), Maps.load(tmp_path / "m")
    assert len(cut_short.extra["t_start_us"]) == 9
    np.testing.assert_array_equal(cut_short.fg_x, limited.fg_x)
    assert cut_short.params["source"]["max_windows"] == 9
    # --force with the same cut file: the run it replaces is that run again
    assert main(["run", str(cut), "--out", str(tmp_path / "o"), *opts, "--force"]) == 2
    assert len(Maps.load(tmp_path / "o").extra["t_start_us"]) == 9
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # nothing set aside is left


def test_events_summarises_a_cut_file_up_to_its_damage_then_says_it(tmp_path, capsys):
    """snn-fg events on a file cut inside an event printed only the error, where run keeps the
    windows before it: the summary now counts the events before the damage, and the error follows."""
    cut = _cut_es(tmp_path)
    assert main(["events", str(cut), "--no-progress"]) == 2
    said = capsys.readouterr()
    assert "events:     399,999 (ON" in said.out
    assert "damaged:    the events above are those before it (byte offset 2000015, event 399999)" in said.out
    err = [line for line in said.err.strip().splitlines() if "warning" not in line]
    assert err == [
        f"snn-fg: error: {cut}: file ends inside an event (2 of 5 bytes) (at byte offset 2000015, event 399999)"
    ]
    assert main(["events", str(cut), "--no-progress", "--write-events", str(tmp_path / "e.npy")]) == 2  # (no file
    assert not (tmp_path / "e.npy").exists()  # is written from a damaged one)


def test_bad_input_before_any_window_keeps_the_earlier_run(tmp_path, capsys):
    """Refused before its first window, a --force run leaves the earlier run as it was."""
    cut = _cut_es(tmp_path)
    opts = ["--no-progress", "--no-figures"]
    assert main(["run", str(tmp_path / "whole.es"), "--out", str(tmp_path / "o"), *opts, "--max-windows", "2"]) == 0
    before = sorted(p.name for p in (tmp_path / "o").iterdir())
    capsys.readouterr()
    cut.write_bytes(cut.read_bytes()[: 20 + 5 * 10 + 1])  # (ten events, then the cut: no window)
    assert main(["run", str(cut), "--out", str(tmp_path / "o"), *opts, "--force"]) == 2
    err = [line for line in capsys.readouterr().err.strip().splitlines() if "warning" not in line]
    assert err == [
        f"snn-fg: error: {cut}: file ends inside an event (1 of 5 bytes); the earlier run in "
        f"{tmp_path / 'o'}/ is kept (at byte offset 70, event 10)"
    ]
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_damage_after_the_last_window_asked_for_is_never_read(tmp_path):
    """The windows asked for end before the damage: they are cut, and the reading stops
    there (a decoder reads 4 MB at a time: it hands over the events before the damage
    first); the damage itself is an error naming its byte offset and event."""
    whole = _cut_es(tmp_path).with_name("whole.es").read_bytes()
    bad = bytearray(whole)
    bad[20 + 5 * 300_000 + 1 : 20 + 5 * 300_000 + 5] = b"\xff\x7f\xff\x7f"  # event 300000 at (32767, 32767)
    (tmp_path / "bad.es").write_bytes(bytes(bad))
    assert len(list(iter_windows(tmp_path / "bad.es", max_windows=7))) == 7  # (to 0.595 s; the damage at 0.6 s)
    with pytest.raises(InputError) as caught:
        list(iter_windows(tmp_path / "bad.es"))
    assert str(caught.value).endswith(
        "event at (x=32767, y=32767) lies outside the 40 x 30 sensor of the header "
        "(at byte offset 1500020, event 300000)"
    )
    seen = []
    with pytest.raises(InputError, match="ends inside an event .*byte offset 2000015, event 399999"):
        for w in iter_windows(tmp_path / "cut.es"):
            seen.append(w.index)
    assert seen == list(range(9))


@pytest.mark.parametrize("damage", ["cut", "bad word", "outside"])
def test_an_evt2_file_is_read_up_to_its_damage_as_every_other_format_is(tmp_path, damage):
    """An EVT2 .raw file cut inside a word, or holding a word of no EVT2 type or an event outside
    the sensor, was refused whole before its first event, naming event 0 (a new user's trial,
    1 Dec): its events before the damage now come as the C decoder gives them for the whole file,
    then the error, with the byte offset and the number of events before it."""
    from snn_fg.events import iter_recording

    rng = np.random.default_rng(3)
    ev = np.zeros(5000, EVENT_DTYPE)
    ev["x"], ev["y"], ev["p"] = rng.integers(0, 64, 5000), rng.integers(0, 48, 5000), rng.integers(0, 2, 5000)
    ev["t"] = np.sort(rng.integers(0, 3_000_000, 5000))  # (3 s: time-high words every 64 us of the clock)
    data = encode_evt2(ev, (64, 48))
    (tmp_path / "whole.raw").write_bytes(data)
    body = data.index(b"% end\n") + len(b"% end\n")
    at = body + 4 * (len(data[body:]) // 8)  # (a word half way through)
    bad = bytearray(data)
    if damage == "cut":
        bad = bad[: at + 3]
    elif damage == "bad word":
        bad[at : at + 4] = (0x5 << 28).to_bytes(4, "little")
    else:
        bad[at : at + 4] = ((1 << 28) | (100 << 11) | 7).to_bytes(4, "little")  # (a CD word at x 100: outside)
    (tmp_path / "bad.raw").write_bytes(bytes(bad))
    whole = np.concatenate(list(iter_recording(tmp_path / "whole.raw")))
    got = []
    with pytest.raises(InputError) as caught:
        for chunk in iter_recording(tmp_path / "bad.raw", chunk_events=700):
            got.append(chunk)
    got = np.concatenate(got)
    assert 0 < len(got) < len(whole) and str(caught.value).endswith(f"(at byte offset {at}, event {len(got)})")
    np.testing.assert_array_equal(got, whole[: len(got)])
    assert len(got) == np.count_nonzero(np.frombuffer(data[body:at], "<u4") >> 28 <= 1)  # (every event before it)


def test_an_nmnist_file_cut_inside_a_record_is_read_up_to_the_cut(tmp_path):
    """A .bin file cut inside its last 5-byte record was refused whole, naming no event."""
    from snn_fg.events import iter_recording

    n = 200
    rec = np.zeros((n, 5), np.uint8)
    rec[:, 0], rec[:, 1] = np.arange(n) % 34, np.arange(n) // 34 % 34
    t = np.arange(n) * 100
    rec[:, 2] = ((np.arange(n) % 2) << 7) | (t >> 16)
    rec[:, 3], rec[:, 4] = (t >> 8) & 0xFF, t & 0xFF
    (tmp_path / "whole.bin").write_bytes(rec.tobytes())
    (tmp_path / "cut.bin").write_bytes(rec.tobytes()[: 5 * 150 + 3])
    whole = np.concatenate(list(iter_recording(tmp_path / "whole.bin")))
    got = []
    with pytest.raises(InputError) as caught:
        for chunk in iter_recording(tmp_path / "cut.bin"):
            got.append(chunk)
    np.testing.assert_array_equal(np.concatenate(got), whole[:150])
    assert str(caught.value).endswith("file ends inside an event (3 of 5 bytes) (at byte offset 750, event 150)")


@pytest.mark.parametrize("suffix, keep", [(".es", 10), (".es", 17), (".raw", 30)])
def test_a_file_cut_inside_its_header_says_so(tmp_path, suffix, keep):
    """A .es file's first 10 bytes were 'a text file, mislabelled?' and a .raw file cut in its header
    line 'unterminated or longer than 4 KiB' (a new user's trial, 1 Dec): each ends inside its header."""
    from snn_fg.events import open_recording

    ev = np.zeros(50, EVENT_DTYPE)
    ev["x"], ev["t"] = np.arange(50) % 40, np.arange(50) * 1000
    whole = tmp_path / f"whole{suffix}"
    save_events(whole, ev, (40, 30))
    cut = tmp_path / f"cut{suffix}"
    cut.write_bytes(whole.read_bytes()[:keep])
    with pytest.raises(InputError, match=rf"file ends inside its header.*byte offset {keep}\)"):
        open_recording(cut, sensor_size=(40, 30) if suffix == ".raw" else None)
