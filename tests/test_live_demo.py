"""`demo` where a command takes a recording: a new user with no camera and no data could not try
`snn-fg live` ("demo: unknown event file extension (none)" from snn-fg stream, "demo: no such file"
from snn-fg events). It is the built-in demo scene seen through the iCub's microsaccade."""

import socket

import numpy as np

from snn_fg.cli.main import main
from snn_fg.events import spif
from snn_fg.frames.scenes import demo_recording


def test_snn_fg_events_demo_describes_the_built_in_recording(capsys):
    rec = demo_recording()
    assert main(["events", "demo", "--no-progress"]) == 0
    said = capsys.readouterr().out
    assert said.startswith("file:       demo (built in: the demo scene, as snn-fg run demo shows it")
    assert "sensor:     160 x 120\n" in said and f"events:     {len(rec.events):,} (ON " in said
    assert f"time span:  {(rec.events['t'][-1] - rec.events['t'][0]) / 1e6:.6f} s" in said
    assert rec.sensor_size == (160, 120, 2) and 2.0 < rec.events["t"][-1] / 1e6 < 2.04  # (24 windows of 85 ms)
    counts = np.bincount(rec.events["t"] // 85_000)  # (one turn a window: every window alike)
    assert len(counts) == 24 and counts.min() == counts.max() > 0


def test_snn_fg_stream_demo_sends_the_built_in_recording(capsys):
    rec = demo_recording()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as inbox:
        inbox.bind(("127.0.0.1", 0))
        inbox.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)  # (every packet kept until read)
        url = f"udp://127.0.0.1:{inbox.getsockname()[1]}"
        assert main(["stream", "demo", "--to", url, "--speed", "20"]) == 0
        inbox.settimeout(0.5)
        packets = []
        try:
            while True:
                packets.append(spif.decode(inbox.recv(65536), 0))
        except TimeoutError:
            pass
    got = np.concatenate(packets)
    assert capsys.readouterr().out.startswith(f"snn-fg: sent {len(rec.events):,} events of demo to {url}")
    assert len(got) == len(rec.events)
    for k in ("x", "y", "p"):
        np.testing.assert_array_equal(got[k], rec.events[k])
    np.testing.assert_array_equal(got["t"], rec.events["t"] - rec.events["t"][0])  # (from 0 at the first event)
