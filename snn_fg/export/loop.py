"""Both ends of a board run, as library functions: where an export's frame is
cut from an input (:func:`outline_crop`, :func:`centroid_crop`,
:func:`crop_events`), whether the input's rate suits the export's gains
(:func:`recalibration_hint`), and the maps of ``run.py``'s counts
(:func:`decode_counts`, with the input's event frame, :func:`input_frame`), and
the maps snn-fg's own engine makes of the same network and input (:func:`reference_maps`).
The commands over them are ``snn-fg events --write-spikes``
(:mod:`snn_fg.cli.spikes`) and ``snn-fg decode`` (:mod:`snn_fg.cli.decode`).
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..models.spiking.decode import decode_maps
from ..network.graph import Network
from ..results.maps import CONFIDENCE, Maps
from .board import board_network
from .lava import SCHEMA as LAVA_SCHEMA
from .nir_folder import SCHEMA as NIR_SCHEMA
from .nir_folder import graph_network
from .pynn import SCHEMA as PYNN_SCHEMA
from .pynn import read_counts, read_input

#: what ran an export folder's run.py, by its network.json's ``schema``: the decoded maps' backend and network
#: origin (until 30 Nov every export's counts were said to be PyNN's)
EXPORT_RUNNERS = {PYNN_SCHEMA: "pynn-export", LAVA_SCHEMA: "lava-export", NIR_SCHEMA: "nir-export"}
#: each runner's export in words (a decoded map's figure says which export ran)
EXPORT_KINDS = {"pynn-export": "PyNN", "lava-export": "Lava", "nir-export": "NIR"}
#: an input whose rate differs from the one the export's gains are set for by more than this factor
#: is driven noticeably differently from how ``snn-fg run`` (which calibrates to its input) drives it
RATE_MISMATCH = 1.2


def export_network(folder):
    """The snn-fg network a PyNN, Lava or NIR export folder's run.py runs (the board network; of a NIR
    export, the network its graph holds: :func:`~snn_fg.export.nir_folder.graph_network`), and its
    ``network.json``."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():  # (before: "DIR/network.json: Not a directory")
        what = "a NIR graph alone" if folder.name.endswith((".nir", ".nir.gz")) else "a file"
        raise InputError(
            folder,
            f"{what}, not an export folder: --export takes the folder snn-fg export --format pynn or lava, "
            "or --format nir --nir-profile snntorch with --out DIR, writes (docs/export.md)",
        )
    path = folder / "network.json"
    try:
        meta = json.loads(path.read_text())
        net = Network.from_dict(meta["snn_fg_network"])
        return (graph_network(net, meta["nir_profile"]) if meta.get("schema") == NIR_SCHEMA else net), meta
    except FileNotFoundError:
        raise InputError(
            path, "no such file: --export needs a folder written by snn-fg export --format pynn, lava or nir"
        ) from None
    except (ValueError, KeyError, TypeError) as e:
        raise InputError(path, f"not an export's network.json ({type(e).__name__}: {e})") from None


def outline_pixels(active: np.ndarray) -> np.ndarray:
    """The active pixels beside an inactive one (4-neighbours; past the input's
    border counts as more of the same): where events outline a region."""
    a = np.asarray(active, bool)
    p = np.pad(a, 1, mode="edge")
    return a & (~p[:-2, 1:-1] | ~p[2:, 1:-1] | ~p[1:-1, :-2] | ~p[1:-1, 2:])


def outline_crop(active: np.ndarray, want) -> tuple:
    """Top-left ``(row, col)`` of the ``want``-sized crop with the most
    :func:`outline_pixels`, the edges whose sides the network decides (the
    crop with the most active pixels lies inside a region of events, where
    there is no edge: all of a 32 x 24 crop of ``dvs.es`` at 100 ms); of
    several such, the one nearest the input's centre."""
    eh, ew = want
    s = np.pad(np.cumsum(np.cumsum(outline_pixels(active).astype(np.int64), 0), 1), ((1, 0), (1, 0)))
    inside = s[eh:, ew:] - s[:-eh, ew:] - s[eh:, :-ew] + s[:-eh, :-ew]
    rows, cols = np.nonzero(inside == inside.max())
    centre = ((active.shape[0] - eh) / 2, (active.shape[1] - ew) / 2)
    best = int(np.argmin(np.hypot(rows - centre[0], cols - centre[1])))
    return int(rows[best]), int(cols[best])


def centroid_crop(events, want, sensor_shape) -> tuple:
    """Top-left ``(row, col)`` of the ``want``-sized (rows, cols) crop
    centred on the mean event position of ``events``, moved inside a sensor
    of ``sensor_shape`` (rows, cols): a moving object stays in view however
    the events are spread, with no look at what the network makes of them."""
    (eh, ew), (h, w) = want, sensor_shape
    r0 = int(np.floor(np.mean(events["y"]) - (eh - 1) / 2 + 0.5))
    c0 = int(np.floor(np.mean(events["x"]) - (ew - 1) / 2 + 0.5))
    return min(max(r0, 0), h - eh), min(max(c0, 0), w - ew)


def crop_events(events, top_left, shape):
    """The events inside the ``shape`` (rows, cols) box at ``top_left`` (row, col), in its coordinates."""
    (r0, c0), (h, w) = top_left, shape
    ev = events[(events["y"] >= r0) & (events["y"] < r0 + h) & (events["x"] >= c0) & (events["x"] < c0 + w)].copy()
    ev["x"] -= c0
    ev["y"] -= r0
    return ev


def rate_mismatch(input_hz: float, export_hz: float) -> bool:
    """Whether an input of ``input_hz`` per active pixel drives an export whose gains are set for
    ``export_hz`` noticeably otherwise than ``snn-fg run`` drives its calibrated network."""
    return input_hz > 0 and max(input_hz, export_hz) > RATE_MISMATCH * min(input_hz, export_hz)


def recalibration_command(input_hz: float, command: str | None, folder=None) -> str:
    """The export command that calibrates the export to ``input_hz`` (``command``: the export's own, if
    known; ``folder``: the export's folder as the user named it now, in place of the ``--out`` the
    command was given, which named it from wherever the export was made)."""
    if not command:
        return f"the export's snn-fg export command with --input-rate-hz {input_hz:.3g}"
    if folder is not None:
        words = shlex.split(command)
        if "--out" in words[:-1]:
            words[words.index("--out") + 1] = str(folder)
            command = " ".join(shlex.quote(w) for w in words)
    return f"{command} --input-rate-hz {input_hz:.3g} --force"


def recalibration_hint(
    input_hz: float, export_hz: float, command: str | None, pixel: str = "pixel", folder=None
) -> str | None:
    """What to do when an input's rate is far from the one the export's gains
    are set for (``snn-fg run`` calibrates its network to its input's rate):
    the command to re-export with (``command``: the export's own, if known; ``folder``: see
    :func:`recalibration_command`)."""
    if not rate_mismatch(input_hz, export_hz):
        return None
    redo = recalibration_command(input_hz, command, folder)
    return (
        f"snn-fg: note: this input is {input_hz:.3g} Hz per active {pixel}, {input_hz / export_hz:.2g} times the "
        f"{export_hz:g} Hz the export's gains are set for; snn-fg run calibrates its network to its input's "
        f"rate. To drive the export as snn-fg run drives the network, re-export: {redo} (it keeps the "
        "folder's input.npz, whose spikes do not depend on the gains)"
    )


def last_spike_frame(inputs):
    """``(pos, neg)`` uint8 event frame of run.py input spikes
    (:class:`~snn_fg.lowering.input_spikes.InputSpikes`): each pixel the
    polarity of its last input spike (within the first period of a
    repeating pattern), as :func:`~snn_fg.events.frame.events_to_frame`
    gives each pixel the polarity of its last event. A pixel whose ON and
    OFF sources last fire in the same step is OFF (an input file holds no
    order within a step; the figures draw OFF over ON too)."""
    h, w = inputs.shape
    n = h * w
    idx, steps = inputs.indices, inputs.steps
    last = np.full(2 * n, -1, np.int64)
    keep = idx < 2 * n  # (the clock source, if any, is no pixel)
    np.maximum.at(last, idx[keep], steps[keep])
    on, off = last[:n], last[n:]
    pos = (on > off).astype(np.uint8)
    neg = ((off >= on) & (off >= 0)).astype(np.uint8)
    return pos.reshape(h, w), neg.reshape(h, w)


def input_frame(path, shape):
    """The event frame (:func:`last_spike_frame`) of a run.py input file of ``shape`` (None: no such file)."""
    if path is None or not Path(path).exists():
        return None
    return last_spike_frame(export_input(path, shape))


def export_input(path, shape):
    """A run.py input file (:func:`~snn_fg.export.pynn.read_input`) for an export's frame ``shape``;
    one line naming it where it is not one, or of another frame."""
    try:
        inp = read_input(path)
    except InputError:
        raise
    except (OSError, ValueError, KeyError) as e:
        raise InputError(path, f"not a run.py input file ({type(e).__name__}: {e})") from None
    if inp.shape != tuple(shape):
        raise InputError(
            path,
            f"an input of {inp.shape[1]} x {inp.shape[0]}, the export's frame is "
            f"{shape[1]} x {shape[0]} (width x height)",
        )
    return inp


def decode_counts(network, counts_path, meta: dict | None = None):
    """:class:`~snn_fg.results.maps.Maps` of ``run.py``'s counts for the export of ``network`` (``meta``:
    its ``network.json``, which says what ran it: :data:`EXPORT_RUNNERS`; a PyNN export without it)."""
    runner = EXPORT_RUNNERS.get((meta or {}).get("schema"), EXPORT_RUNNERS[PYNN_SCHEMA])
    try:
        result = read_counts(network, counts_path)
    except InputError:
        raise
    except (OSError, ValueError, KeyError) as e:
        raise InputError(counts_path, f"not a run.py counts file of this export ({type(e).__name__}: {e})") from None
    return _maps(network, result, {"name": runner, "counts": str(counts_path)}, runner)


def reference_maps(network, like: Maps, input_path, backend: str = "fast") -> Maps:
    """The maps of the same exported network (as exported: its gains, every cell),
    simulated by snn-fg's ``backend`` on the same input file over the span and count
    window of the board's run (``like``: its :func:`decode_counts` maps): what the
    board's maps are checked against, like for like."""
    from ..backends import RunSettings, get_backend

    sim = like.params["simulation"]
    duration, window = float(sim["duration_ms"]), float(sim["count_window_ms"])
    net = board_network(network)
    inp = export_input(input_path, net.frame_shape)
    settings = RunSettings(
        duration_ms=duration, dt_ms=float(sim["dt_ms"]), count_from_ms=duration - window, instantiate="all"
    )
    result = get_backend(backend).simulate(net, inp, settings)
    return _maps(network, result, {"name": backend, "input": str(input_path)}, like.params["network"]["origin"])


def _maps(network, result, backend: dict, origin: str) -> Maps:
    """The maps of a board network's run (``result``), with what made them (``origin``: the export's kind)."""
    fg_x, fg_y, grouping, conf = decode_maps(result)
    params = {
        "model": "spiking",
        **network.params.to_dict(),
        "network": {
            "origin": origin,
            "frame_shape": list(network.frame_shape),
            "input_rate_hz": network.input_rate_hz,
        },
        "backend": backend,
        "simulation": {
            "dt_ms": result.dt_ms,
            "duration_ms": result.simulated_ms,
            "count_window_ms": result.count_window_ms,
        },
        "notes": list(network.notes),
    }
    extra = {CONFIDENCE: conf.astype(np.float32)}
    return Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), params, extra)
