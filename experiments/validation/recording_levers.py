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
  read-out span only (``readout_ms``), once the network has settled on it.

Writes ``recording_levers.{json,md}``.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from dataclasses import replace

import numpy as np

from experiments.common import Run, describe, markdown_table, save_results
from experiments.validation.recording_fidelity import RECORDINGS, inward, rate_maps, scores, windows_of

#: (label, input, time scale, run options): sliding and latched input at three speeds
LEVERS = (
    ("sliding, whole span", "sliding", 1.0, {}),
    ("sliding, last 30 ms (lag 10)", "sliding", 1.0, {"readout_ms": 30.0, "readout_lag_ms": 10.0}),
    ("sliding, x1/2, last 30 ms (lag 10)", "sliding", 0.5, {"readout_ms": 30.0, "readout_lag_ms": 10.0}),
    ("sliding, x1/4, last 30 ms (lag 10)", "sliding", 0.25, {"readout_ms": 30.0, "readout_lag_ms": 10.0}),
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
    out = []
    for w in wins:
        ys, xs = np.nonzero(w.pos | w.neg)
        ev = np.zeros(xs.size, dtype=w.events.dtype)
        ev["x"], ev["y"], ev["t"], ev["p"] = xs, ys, w.t_end_us, w.pos[ys, xs] != 0
        out.append(replace(w, events=ev))
    return out


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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=6, help="windows per recording (6)")
    ap.add_argument("--only", nargs="+", choices=sorted(RECORDINGS), default=["dvs_biplane", "person"])
    ap.add_argument("--default", action="store_true", help="the default network too (slow: minutes a window)")
    a = ap.parse_args()
    run = Run()
    results, lines = {}, []
    for name in a.only:
        wins = windows_of(name, a.windows)
        rows, table = [], []
        for network in ("compact", "default") if a.default else ("compact",):
            ref = rate_maps(wins, network)
            for label, how, scale, options in LEVERS:
                if network == "default" and label not in DEFAULT_LEVERS:
                    continue
                maps, per_window_s = run_lever(wins, network, how, scale, options)
                row = {"network": network, "lever": label, "s_per_window": per_window_s, **scores(maps, ref)}
                if name == "dvs_biplane":
                    row["inward"] = inward(maps, wins)
                rows.append(row)
                print(f"{name} {network} {label}: {row['within_45']:.3f} within 45 deg", flush=True)
                per = row["within_45_per_window"]
                table.append(
                    [
                        network,
                        label,
                        f"{row['within_45']:.1%} ({np.nanmin(per):.0%}-{np.nanmax(per):.0%})",
                        f"{row['mean_abs_deg']:.1f}",
                        f"{row['grouping_r_mean']:.3f}",
                        f"{row['coverage']:.1%}",
                        f"{np.median(row['inward']):.2f}" if "inward" in row else "",
                        f"{per_window_s:.2f}",
                    ]
                )
        results[name] = rows
        file, window_ms, start_ms, _ = RECORDINGS[name]
        lines += [
            f"## {name} (`{file}`, {len(wins)} windows of {window_ms:g} ms from {start_ms:g} ms)",
            "",
            *markdown_table(
                [
                    "network",
                    "input, speed, read-out",
                    "within 45° of the rate model (pooled; per window)",
                    "mean abs °",
                    "grouping r",
                    "coverage",
                    "plane outline inward (median)",
                    "s per window",
                ],
                table,
            ),
            "",
        ]
    head = ["# Levers on the spiking network's agreement with the rate model on recordings", "", describe(run.record())]
    head += ["", "Scored as in `recording_fidelity.md`; the levers: the module docstring.", ""]
    save_results("recording_levers", {"run": run.record(), "recordings": results}, head + lines)


if __name__ == "__main__":
    main()
