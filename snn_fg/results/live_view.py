"""The live page of ``snn-fg live --view PORT``: on ``http://127.0.0.1:PORT/``
(``--view-host``), the latest window's event frame, figure-ground map and
grouping map, with its latency and the windows published, dropped and
skipped so far, updating as windows are published.

A server thread (the standard library's ``http.server``) answers the page,
``/state.json`` (the latest window's published line, :mod:`.publish`, with
the run's ``windows``, ``windows_dropped`` and ``windows_skipped`` so far) and
one PNG per panel, ``/events.png``, ``/fg.png``, ``/grouping.png``, of the
window ``?w=K`` names (the latest one if that has passed). The model's
thread only hands over its arrays (:meth:`LiveView.show`); a panel is coloured
(as the run's figures colour it, :mod:`snn_fg.results.figures`) and encoded when a
browser asks for it, once per window.
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import urlsplit

import numpy as np

from snn_fg.errors import InputError

#: the panels of the page: path -> title
PANELS = {"events": "event frame", "fg": "figure-ground map", "grouping": "grouping map"}
#: how often the page asks for the latest window (ms)
POLL_MS = 100

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>snn-fg live</title>
<style>
body {{ font-family: sans-serif; background: #222; color: #eee; margin: 1em; }}
.panels {{ display: flex; gap: 1em; flex-wrap: wrap; }}
figure {{ margin: 0; }} img.panel {{ width: 320px; image-rendering: pixelated; background: #000; }}
img.key {{ width: 90px; vertical-align: middle; }}
</style></head>
<body data-updates="0" data-window="">
<h1>snn-fg live: {source}</h1>
<p id="status">waiting for the first window</p>
<p id="counts"></p>
<div class="panels">{panels}</div>
<script>
let shown = null;
async function poll() {{
  try {{
    const s = await (await fetch('/state.json', {{cache: 'no-store'}})).json();
    if (s.window !== null && s.window !== shown) {{
      shown = s.window;
      for (const img of document.querySelectorAll('img.panel')) img.src = '/' + img.id + '.png?w=' + s.window;
      const k = s.peaks[0];
      const p = k ? `, strongest proto-object at x ${{k.x}}, y ${{k.y}} (from the top left)` : '';
      document.getElementById('status').textContent = `window ${{s.window}}, ` +
        `${{(s.t_start_us / 1000).toFixed(0)}}-${{(s.t_end_us / 1000).toFixed(0)}} ms, ${{s.events}} events, ` +
        `latency ${{s.latency_ms === null ? '-' : s.latency_ms.toFixed(1)}} ms${{p}}`;
      if (s.windows !== undefined) document.getElementById('counts').textContent = `windows: ${{s.windows}} ` +
        `published, ${{s.windows_dropped}} dropped, ${{s.windows_skipped}} skipped for a newer hop`;
      document.body.dataset.updates = Number(document.body.dataset.updates) + 1;
      document.body.dataset.window = s.window;
    }}
  }} catch (e) {{ document.getElementById('status').textContent = 'the run has ended'; }}
  setTimeout(poll, {poll_ms});
}}
poll();
</script></body></html>
"""
PANEL = '<figure><img class="panel" id="{name}" alt="{title}" onload="this.dataset.loaded = this.naturalWidth">'
PANEL += "<figcaption>{title}{key}</figcaption></figure>"
#: the figure-ground panel's key: the colour wheel of maps.png (hue: the direction towards the figure, x right and
#: y up; brightness: strength), drawn once as the page is made
KEY = ' <img class="key" src="/key.png" alt="colour wheel: hue is the direction, 0 degrees right, 90 up">'


#: where the page is served unless ``--view-host`` says otherwise: this machine alone
VIEW_HOST = "127.0.0.1"


class LiveView:
    """The page on ``http://host:port/`` (``port`` 0: any free one, :attr:`port`),
    served on a thread of its own until :meth:`close`."""

    def __init__(self, port: int, source: str = "", host: str = VIEW_HOST):
        from snn_fg.results import figures  # noqa: F401 - (matplotlib loaded now, not as the first window is shown)

        panels = "".join(PANEL.format(name=k, title=v, key=KEY if k == "fg" else "") for k, v in PANELS.items())
        self.key = _wheel_png()
        self.page = PAGE.format(source=source, panels=panels, poll_ms=POLL_MS).encode()
        self.lock = threading.Lock()
        self.latest = None  # (message, arrays) of the latest window
        self.encoded: dict = {}  # panel -> (window, png) of the latest window
        try:
            self.server = ThreadingHTTPServer((host, port), _handler(self))
        except OSError as exc:
            where = f"--view {port}" + ("" if host == VIEW_HOST else f" --view-host {host}")
            raise InputError(where, f"cannot serve the page there: {exc.strerror or exc}") from None
        self.host = host
        self.server.daemon_threads = True
        self.port = self.server.server_address[1]
        self.thread = threading.Thread(target=self.server.serve_forever, name="snn-fg live view", daemon=True)
        self.thread.start()

    def show(self, w, maps, message: dict) -> None:
        """Window ``w``'s maps are published (``message``, its JSON line): the page shows them next."""
        with self.lock:
            self.latest = message, (w.pos, w.neg, maps.fg_x, maps.fg_y, maps.grouping)

    def state(self) -> dict:
        with self.lock:
            return {"window": None} if self.latest is None else self.latest[0]

    def png(self, panel: str) -> bytes | None:
        """The latest window's ``panel`` as a PNG (None before the first window)."""
        with self.lock:
            if self.latest is None:
                return None
            message, arrays = self.latest
            k = message["window"]
            cached = self.encoded.get(panel)
            if cached is not None and cached[0] == k:
                return cached[1]
        data = _encode(panel_rgb(panel, *arrays))
        with self.lock:
            self.encoded[panel] = k, data
        return data

    def close(self):
        self.server.shutdown()
        self.server.server_close()
        self.thread.join(timeout=2)


def panel_rgb(panel: str, pos, neg, fg_x, fg_y, grouping) -> np.ndarray:
    """One panel as an RGB image (floats in [0, 1]), coloured as the run's figures colour it."""
    from matplotlib import colormaps

    from snn_fg.results.figures import GROUPING_CMAP, event_frame_rgb, fg_rgb

    if panel == "events":
        return event_frame_rgb(pos, neg)
    if panel == "fg":
        return fg_rgb(fg_x, fg_y)
    g = np.asarray(grouping, dtype=np.float64)
    top = g.max() if g.size and g.max() > 0 else 1.0
    return colormaps[GROUPING_CMAP](np.clip(g / top, 0, 1))[..., :3]


def _wheel_png() -> bytes:
    """The colour wheel of :func:`~snn_fg.results.figures.draw_wheel` as a PNG, light on the page's dark ground."""
    import io

    from matplotlib import rc_context
    from matplotlib.figure import Figure  # (no pyplot: nothing global, no GUI backend)

    from snn_fg.results.figures import draw_wheel

    with rc_context({"text.color": "#eee"}):
        fig = Figure(figsize=(1.2, 1.1), dpi=100)
        draw_wheel(fig.add_axes([0, 0, 1, 1]))
        buf = io.BytesIO()
        fig.savefig(buf, format="png", transparent=True)
    return buf.getvalue()


def _encode(rgb: np.ndarray) -> bytes:
    import cv2

    ok, data = cv2.imencode(".png", np.ascontiguousarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8)[..., ::-1]))
    return data.tobytes()


def _handler(view: LiveView):
    class Handler(BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 - (http.server's name)
            path = urlsplit(self.path).path.strip("/")  # (?w=K only makes each window's address its own)
            if path in ("", "index.html"):
                self._send(200, "text/html; charset=utf-8", view.page)
            elif path == "key.png":
                self._send(200, "image/png", view.key)
            elif path == "state.json":
                self._send(200, "application/json", json.dumps(view.state()).encode())
            elif path.endswith(".png") and path[:-4] in PANELS:
                data = view.png(path[:-4])
                if data is None:
                    self._send(404, "text/plain", b"no window yet\n")
                else:
                    self._send(200, "image/png", data)
            else:
                self._send(404, "text/plain", b"not here\n")

        def _send(self, code: int, kind: str, body: bytes):
            self.send_response(code)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):  # (no line per request on stderr)
            pass

    return Handler
