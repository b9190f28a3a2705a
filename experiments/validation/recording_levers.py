"""Levers on the spiking network's agreement with the rate model on recordings: input, speed, read-out.

    python -m experiments.validation.recording_levers [--windows 6] [--only dvs_biplane person] [--default]

The rate model reads each window's whole event frame and iterates on it ten
times from a fresh start; the network reads the events as they come and
needs about 200-400 ms to settle on a still frame (``recording_diagnosis.md``).
Three levers act on that, each measured here on the compact network against
the rate model on its recipe (``--default``: the default network too, with
the latched input at x1/4, about 10x its time a window), on the windows of ``recording_fidelity``:

* input: ``sliding`` (each pixel's last polarity held for one window's
  length after its event, not cleared as a window starts: at the window's
  end exactly the window's frame) or ``latched`` (each window's frame,
  complete at its end, held whole through the next window: one window of
  latency; made here by moving each window's frame to its end);
* speed: the network with every time constant, delay, refractory period and
  time step scaled by ``s`` and every rate by ``1 / s`` (the weights stay as
  they are: the same network in faster time, at ``1 / s`` times the spikes
  and ``1 / s**2`` times the work);
* read-out: the spikes of each window counted over the last 40 ms of its
  read-out span only (``readout_ms``), once the network has settled on it;
* the window clock off (the grouping not started afresh at each window:
  the network settles across windows on the sliding input).

Writes ``recording_levers.{json,md}``. ``--figure`` instead draws window 3 of
``dvs.es`` (the one ``recording_fidelity.png`` shows), run alone, for the rate
model and the default network with the events, the sliding and the latched
x1/4 input: ``recording_levers.png``.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from dataclasses import replace

from experiments.common import Run, describe, save_figure, save_results
from experiments.validation.recording_fidelity import (
    RECORDINGS,
    frame_events,
    inward,
    rate_maps,
    scores,
    table_lines,
    windows_of,
)

#: (label, input, time scale, run options): sliding and latched input at three speeds
LEVERS = (
    ("sliding, whole span", "sliding", 1.0, {}),
    ("sliding, last 30 ms (lag 10)", "sliding", 1.0, {"readout_ms": 30.0, "readout_lag_ms": 10.0}),
    ("sliding, x1/2, last 30 ms (lag 10)", "sliding", 0.5, {"readout_ms": 30.0, "readout_lag_ms": 10.0}),
    ("sliding, x1/4, last 30 ms (lag 10)", "sliding", 0.25, {"readout_ms": 30.0, "readout_lag_ms": 10.0}),
    (
        "sliding, no window clock, last 30 ms (lag 10)",
        "sliding",
        1.0,
        {"readout_ms": 30.0, "readout_lag_ms": 10.0, "window_clock": False},
    ),
    ("latched, last 40 ms of the next window", "latched", 1.0, {"readout_ms": 40.0}),
    ("latched, x1/2, last 40 ms of the next window", "latched", 0.5, {"readout_ms": 40.0}),
    ("latched, x1/4, last 40 ms of the next window", "latched", 0.25, {"readout_ms": 40.0}),
)
#: the levers the default network is run with under ``--default`` (x1/4: about 10x its time a window)
DEFAULT_LEVERS = ("latched, x1/4, last 40 ms of the next window",)


@contextlib.contextmanager
def reference_rates(scale: float):
    """The gains' reference rates (``snn_fg.network.spiking_params``) times ``1 / scale`` while
    networks are built, so that a time-scaled network keeps its weights in millivolts."""
    import snn_fg.network.gains as gains
    import snn_fg.network.spiking_params as sp
    import snn_fg.network.stages as stages

    names = ("SIMPLE_RATE_HZ", "UNTUNED_RATE_HZ", "CELL_RATE_HZ")
    kept = {(m, n): getattr(m, n) for m in (gains, stages) for n in names if hasattr(m, n)}
    try:
        for m, n in kept:
            setattr(m, n, getattr(sp, n) / scale)
        yield
    finally:
        for (m, n), v in kept.items():
            setattr(m, n, v)


def time_scaled(spiking, scale: float):
    """``spiking`` with every time constant, refractory period, delay and the time step times
    ``scale`` and the input rate times ``1 / scale`` (built under :func:`reference_rates`)."""
    from snn_fg.network.spiking_params import CELL_KINDS

    n, i, t = spiking.neurons, spiking.input, spiking.time
    neurons = n.replace(
        **{
            k: replace(
                getattr(n, k),
                **{f: getattr(getattr(n, k), f) * scale for f in ("tau_m_ms", "tau_exc_ms", "tau_inh_ms", "t_ref_ms")},
            )
            for k in CELL_KINDS
        }
    )
    inp = i.replace(
        input_rate_hz=i.input_rate_hz / scale,
        input_refractory_ms=i.input_refractory_ms * scale,
        gate_spread_ms=i.gate_spread_ms * scale,
    )
    timing = t.replace(
        **{f: getattr(t, f) * scale for f in ("dt_ms", "delay_ms", "delay_untuned_ms", "delay_feedback_ms")}
    )
    return spiking.replace(neurons=neurons, input=inp, time=timing)


def latched(wins):
    """Each window with its events replaced by its event frame at its end (the next window's start)."""
    return [replace(w, events=frame_events(w, w.t_end_us)) for w in wins]


def run_lever(wins, network: str, how: str, scale: float, options: dict):
    from snn_fg.models.spiking import run_spiking_windows
    from snn_fg.network.recipes import RECIPES

    recipe = RECIPES[network]
    window_ms = (wins[0].t_end_us - wins[0].t_start_us) / 1000.0
    if how == "latched":  # (read over the next window, where the frame is held)
        options = {**options, "readout_lag_ms": window_ms + options.get("readout_lag_ms", 0.0)}
    t = time.perf_counter()
    with reference_rates(scale):
        maps = run_spiking_windows(
            latched(wins) if how == "latched" else wins,
            params=recipe.params,
            spiking=time_scaled(recipe.spiking, scale),
            input_coding="window" if how == "latched" else "sliding",
            progress=False,
            **options,
        )
    return maps, (time.perf_counter() - t) / len(wins)


def figure():
    import matplotlib

    matplotlib.use("Agg")  # (an experiment script, never imported by the package)
    import matplotlib.pyplot as plt

    from snn_fg.models.spiking import run_spiking_windows
    from snn_fg.results.figures import event_frame_rgb, fg_rgb
    from snn_fg.scoring.metrics import agreement

    w = windows_of("dvs_biplane", 4)[3:]
    ref = rate_maps(w, "default")[0]
    panels = [("events", event_frame_rgb(w[0].pos, w[0].neg)), ("rate model", fg_rgb(ref.fg_x, ref.fg_y))]
    for label, m in (
        ("spiking, events coding", run_spiking_windows(w, progress=False)[0]),
        ("spiking, sliding coding", run_spiking_windows(w, input_coding="sliding", progress=False)[0]),
        ("spiking, latched, x1/4", run_lever(w, "default", "latched", 0.25, {"readout_ms": 40.0})[0][0]),
    ):
        panels.append((f"{label}: {agreement(m, ref)['within_45']:.0%} within 45°", fg_rgb(m.fg_x, m.fg_y)))
    fig, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 3.4), squeeze=False)
    for ax, (title, img) in zip(axes[0], panels):
        ax.imshow(img)
        ax.set_title(f"dvs.es window 3, default network: {title}" if title == "events" else title, fontsize=9)
        ax.set_xlabel("x (px)")
        ax.set_ylabel("y (px)")
    fig.tight_layout()
    return fig


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=6, help="windows per recording (6)")
    ap.add_argument("--only", nargs="+", choices=sorted(RECORDINGS), default=["dvs_biplane", "person"])
    ap.add_argument("--default", action="store_true", help="the default network too (slow: minutes a window)")
    ap.add_argument("--figure", action="store_true", help="only the figure of one dvs.es window (see above)")
    a = ap.parse_args()
    if a.figure:
        save_figure(figure(), "recording_levers")
        return
    run = Run()
    results = {}
    for name in a.only:
        wins = windows_of(name, a.windows)
        rows = []
        for network in ("compact", "default") if a.default else ("compact",):
            ref = rate_maps(wins, network)
            for label, how, scale, options in LEVERS:
                if network == "default" and label not in DEFAULT_LEVERS:
                    continue
                maps, per_window_s = run_lever(wins, network, how, scale, options)
                row = {"network": network, "map": label, "s_per_window": per_window_s, **scores(maps, ref)}
                if name == "dvs_biplane":
                    row["inward"] = inward(maps, wins)
                rows.append(row)
                print(f"{name} {network} {label}: {row['within_45']:.3f} within 45 deg", flush=True)
        results[name] = {"windows": len(wins), "rows": rows}
    head = ["# Levers on the spiking network's agreement with the rate model on recordings", "", describe(run.record())]
    head += ["", "Scored as in `recording_fidelity.md`; the maps: the levers of the module docstring.", ""]
    save_results("recording_levers", {"run": run.record(), "recordings": results}, head + table_lines(results))


if __name__ == "__main__":
    main()
