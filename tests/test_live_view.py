"""The live page (snn-fg live --view): its HTTP endpoints answered by a plain
client, and the page itself in a headless browser (Chromium from the system's
packages), which must load it, show the three panels and follow the windows."""

import json
import re
import shutil
import subprocess
import threading
import time
import urllib.error
import urllib.request
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from snn_fg.results.live_view import PANELS, LiveView
from snn_fg.results.maps import Maps

#: the headless browsers looked for (Debian: chromium-headless-shell, or chromium)
BROWSERS = ("chromium-headless-shell", "chromium", "chromium-browser", "google-chrome")


def _window(k: int, w: int = 40, h: int = 30):
    """Window ``k``: an ON event at (5, 5), an OFF one at (6, 5), a rightward
    figure-ground vector at (10, 20) and a grouping peak at (30, 12)."""
    pos, neg = np.zeros((h, w), bool), np.zeros((h, w), bool)
    pos[5, 5], neg[5, 6] = True, True
    fx, fy, g = (np.zeros((h, w), np.float32) for _ in range(3))
    fx[20, 10], g[12, 30] = 1.0, 5.0 + k
    message = {"window": k, "t_start_us": 85_000 * k, "t_end_us": 85_000 * (k + 1), "events": 2, "latency_ms": 12.5}
    message["peaks"] = [{"x": 30, "y": 12, "strength": 5.0 + k, "fg_x": 0.0, "fg_y": 0.0, "fg_deg": 0.0}]
    message |= {"windows": k + 1, "windows_dropped": 2 * k, "windows_skipped": 3 * k}  # (the run's, as LiveRecord adds)
    return SimpleNamespace(pos=pos, neg=neg), Maps(fx, fy, g), message


def _get(port, path):
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=5) as r:
        return r.status, r.headers["Content-Type"], r.read()


@pytest.fixture
def view():
    v = LiveView(0, "udp://127.0.0.1:3333")
    yield v
    v.close()


def test_the_page_serves_the_latest_window_as_three_panels_and_its_state(view):
    status, kind, page = _get(view.port, "/")
    assert status == 200 and kind.startswith("text/html")
    assert all(f'id="{name}"' in page.decode() for name in PANELS)
    assert json.loads(_get(view.port, "/state.json")[2]) == {"window": None}
    with pytest.raises(urllib.error.HTTPError) as none_yet:
        _get(view.port, "/fg.png")
    assert none_yet.value.code == 404
    view.show(*_window(3))
    state = json.loads(_get(view.port, "/state.json")[2])
    assert state["window"] == 3 and state["latency_ms"] == 12.5 and state["peaks"][0]["x"] == 30
    img = {}
    for name in PANELS:
        status, kind, data = _get(view.port, f"/{name}.png?w=3")
        assert status == 200 and kind == "image/png"
        img[name] = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[..., ::-1]  # (RGB)
        assert img[name].shape == (30, 40, 3)
    ev = img["events"]
    assert ev[5, 5].tolist() == [255, 255, 255] and ev[5, 6].tolist() == [0, 0, 0] and ev[0, 0].tolist() == [127] * 3
    assert img["fg"][20, 10].tolist() == [255, 0, 0] and img["fg"][0, 0].tolist() == [0, 0, 0]  # (0 degrees: red)
    g = img["grouping"].astype(int).sum(axis=2)
    assert np.unravel_index(np.argmax(g), g.shape) == (12, 30)
    status, kind, key = _get(view.port, "/key.png")  # (the figure-ground panel's colour wheel)
    wheel = cv2.imdecode(np.frombuffer(key, np.uint8), cv2.IMREAD_UNCHANGED)
    assert status == 200 and kind == "image/png" and 'src="/key.png"' in page.decode()
    h, w = wheel.shape[:2]
    right = wheel[h // 2, int(w * 0.74), :3][::-1]  # (RGB, near the rim right of the centre: 0 degrees, red)
    assert right[0] > 200 and right[1] < 80 and right[2] < 80, right
    with pytest.raises(urllib.error.HTTPError) as elsewhere:
        _get(view.port, "/nothing")
    assert elsewhere.value.code == 404


def test_a_port_taken_is_one_line():
    from snn_fg.errors import InputError

    taken = LiveView(0)
    try:
        with pytest.raises(InputError, match=f"--view {taken.port}: cannot serve the page there"):
            LiveView(taken.port)
    finally:
        taken.close()
    with pytest.raises(InputError, match="--view 0 --view-host 256.1.1.1: cannot serve the page there"):
        LiveView(0, host="256.1.1.1")


def test_the_page_is_served_on_the_host_asked_for():
    """--view-host: here another of this machine's loopback addresses (0.0.0.0 would be every network)."""
    view = LiveView(0, host="127.0.0.2")
    try:
        with urllib.request.urlopen(f"http://127.0.0.2:{view.port}/state.json", timeout=5) as r:
            assert json.loads(r.read()) == {"window": None}
        with pytest.raises(urllib.error.URLError):
            _get(view.port, "/state.json")  # (not on 127.0.0.1)
    finally:
        view.close()


def _browser():
    return next((shutil.which(b) for b in BROWSERS if shutil.which(b)), None)


@pytest.mark.skipif(_browser() is None, reason="no headless Chromium here (apt-get install chromium-headless-shell)")
def test_the_live_page_in_a_headless_browser_loads_shows_the_three_panels_and_updates(view):
    """Windows are shown every 40 ms while Chromium loads the page and runs it
    for 4 s (of its virtual time): the page it leaves has followed several
    windows, and each panel holds a decoded image of the sensor's width."""
    stop = threading.Event()

    def windows():
        k = 0
        while not stop.is_set():
            view.show(*_window(k))
            k += 1
            time.sleep(0.04)

    feeder = threading.Thread(target=windows)
    feeder.start()
    try:
        dom = subprocess.run(
            [_browser(), "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=4000", "--dump-dom"]
            + [f"http://127.0.0.1:{view.port}/"],
            capture_output=True,
            text=True,
            timeout=60,
        ).stdout
    finally:
        stop.set()
        feeder.join()
    body = re.search(r"<body([^>]*)>", dom).group(1)
    assert int(re.search(r'data-updates="(\d+)"', body).group(1)) >= 2
    for name in PANELS:
        img = re.search(rf'<img[^>]*id="{name}"[^>]*>', dom).group(0)
        assert 'data-loaded="40"' in img, img  # (naturalWidth: the PNG decoded)
    status = re.search(r'<p id="status">([^<]*)</p>', dom).group(1)
    head = r"window \d+, \d+-\d+ ms, 2 events, latency 12.5 ms, "
    assert re.match(head + r"strongest proto-object at x 30, y 12 \(from the top left\)", status)
    k = int(re.search(r'data-window="(\d+)"', body).group(1))  # (the run's counts, as of the window shown)
    counts = re.search(r'<p id="counts">([^<]*)</p>', dom).group(1)
    assert counts == f"windows: {k + 1} published, {2 * k} dropped, {3 * k} skipped for a newer hop"
