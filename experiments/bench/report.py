"""Printing the benchmark's results: tables and the ratios between engines."""

from __future__ import annotations

import statistics

from .child import AUTHORS_CORRELATES_PER_FRAME


def _load(entry) -> str:
    text = entry.get("load_before", "")
    return text[text.find("load average") :] if "load average" in text else text


def _rows(m):
    return m.get("result", []) if isinstance(m, dict) else [r for x in m for r in x.get("result", [])]


def _frames(data):
    print("\n== BSDS frames (321 x 481): median s per frame ==")
    rate = {r["input"]: r for r in _rows(data.get("rate", []))}
    for eng, ms in data.items():
        if not isinstance(ms, list):
            continue
        for m in ms:
            if "error" in m:
                print(f"  {eng:16s} ERROR {m['error']}")
            for r in m.get("result", []):
                extra = ""
                if "ratio_vs_authors" in r:
                    extra = (
                        f"  authors {r['authors_frame_s']:.0f} s (955 x correlate {r['correlate_median_s']:.3f} s)"
                        f"  -> {r['ratio_vs_authors']:.0f}x faster"
                    )
                elif r["input"] in rate:
                    extra = f"  = {r['median_s'] / rate[r['input']]['median_s']:.0f}x the rate model"
                print(
                    f"  {eng:16s} {r['input']:12s} {r['median_s']:8.3f} s  peak {m['peak_rss_mb']:6.0f} MB{extra}"
                    f"   [{_load(m)}]"
                )
    if rate:
        ratios = [r["ratio_vs_authors"] for r in rate.values()]
        print(
            f"  rate model vs the authors' code, median over {len(ratios)} frames: "
            f"{statistics.median(ratios):.0f}x (authors' frame time = {AUTHORS_CORRELATES_PER_FRAME} x one "
            f"scipy.ndimage.correlate 321x481 * 49x49, timed in the same process before each repeat)"
        )


def _per_window(title, data):
    print(f"\n== {title} ==")
    med, by_input = {}, {}
    for eng, m in data.items():
        if not isinstance(m, dict) or "load_before" not in m:
            continue
        if "error" in m:
            print(f"  {eng:16s} ERROR {m['error']}")
            continue
        rows = m["result"]
        med[eng] = statistics.median(r["median_s"] for r in rows)
        by_input[eng] = {r["input"]: r["median_s"] for r in rows}
        ev = [r["n_events"] for r in rows]
        print(
            f"  {eng:16s} {len(rows)} windows ({min(ev)}-{max(ev)} events): median {med[eng]:.3f} s per window, "
            f"peak {m['peak_rss_mb']:.0f} MB   [{_load(m)}]"
        )
    for eng, times in by_input.items():
        common = sorted(set(times) & set(by_input.get("rate", {})))
        if eng != "rate" and common:
            ratio = statistics.median(times[k] / by_input["rate"][k] for k in common)
            print(f"  {eng} / rate on the same {len(common)} input(s) ({', '.join(common)}): {ratio:.0f}x")
    return med


def _synthetic(data):
    _per_window("synthetic 85 ms windows", data)
    for eng, m in data.items():
        for r in m.get("result", []):
            cpu = f", CPU {r['cpu_median_s']:.4f} s" if "cpu_median_s" in r else ""
            print(f"    {eng:14s} {r['n_events']:7d} events ({r['active_pixels']:6d} px): {r['median_s']:.4f} s{cpu}")
        for key, clock in (("scaling", "wall"), ("scaling_cpu", "CPU")):
            fit = m.get(key)
            if fit:
                print(
                    f"  {eng}: {clock} time per window = {fit['fixed_ms']:.1f} ms + "
                    f"{fit['slope_us_per_event']:.3f} us x events (R^2 {fit['r2']:.3f})"
                )


def _failed(eng: str, r: dict, width: int) -> bool:
    """Print a failed command run's line; whether it failed."""
    if r.get("exit_status"):
        print(f"  {eng:{width}s} FAILED (exit {r['exit_status']})")
    return bool(r.get("exit_status"))


def _throughput(data):
    print("\n== snn-fg run dvs.es --window-ms 85, end to end ==")
    for eng, r in data.items():
        if _failed(eng, r, 16):
            continue
        print(
            f"  {eng:16s} {r['windows']} of {r['windows_in_recording']} windows in {r['wall_s']:.1f} s: "
            f"{r['windows_per_s']:.3g} windows/s ({r['s_per_window']:.3g} s per window), "
            f"peak {r['peak_rss_mb']:.0f} MB   [{_load(r)}]"
        )


#: the real-time budget: one 85 ms window of events per 85 ms of wall time
REAL_TIME_S = 0.085


def _stream(data):
    print("\n== snn-fg run REC --start-ms 100 --no-figures: seconds per 85 ms window, beyond the first ==")
    rows = {k: v for k, v in data.items() if k not in ("floor", "summary")}
    for eng, r in rows.items():
        if _failed(eng, r, 40):
            continue
        ev = ""
        if "cpu_ns_per_synaptic_event" in r:
            ev = (
                f", {r['synaptic_events_per_window']:.3g} synaptic events at {r['cpu_ns_per_synaptic_event']:.1f} ns "
                "of CPU"
            )
        rounds, each = "", r.get("rounds_median_window_s", [])
        if len(each) > 1:
            rounds = f" (rounds {1000 * min(each):.0f}-{1000 * max(each):.0f} ms)"
        print(
            f"  {eng:40s} median {1000 * r['median_window_s']:7.1f} ms{rounds} "
            f"({'within' if r['median_window_s'] <= REAL_TIME_S else 'over'} real time; whole run "
            f"{1000 * r['wall_s_per_window']:.0f} ms per window{ev}), peak {r['peak_rss_mb']:.0f} MB   [{_load(r)}]"
        )
    for f in data.get("floor", {}).get("rounds", []):
        state = ", ".join(f"{k} {v:.2f}" for k, v in f.get("state_random", {}).items())
        print(
            f"  floor (state[idx[k]] += w[k]): random in {f['in_cache_mb']} MB {f['in_cache_random']:.2f} ns, "
            f"contiguous {f['contiguous']:.2f} ns, random in {f['large_mb']:.0f} MB {f['large_random']:.2f} ns; "
            f"random in a network's cell state: {state}"
        )
    for name, s in data.get("summary", {}).items():
        if name.startswith("peer_"):
            print(
                f"  {name[5:]} on the compact network, first {s['windows']} windows: {s['wall_s_per_window']:.2f} s "
                f"per window against {s['fast_wall_s_per_window']:.3f} s on the fast engine: {s['ratio']:.0f}x"
            )
            continue
        two = ""
        if "speedup_2_cores" in s:
            two = f"; two cores {1000 * s['median_window_s_2_cores']:.0f} ms a window, {s['speedup_2_cores']:.2f}x one"
        ratio = f"{s['ratio_to_floor']:.1f}x" if s.get("ratio_to_floor") else "-"
        print(
            f"  {name}: {s['synaptic_events_per_window']:.3g} synaptic events a window, "
            f"{s['cpu_ns_per_event_1_core']:.2f} ns of CPU each on one core = {ratio} the in-cache floor "
            f"({s['floor_in_cache_ns']:.2f} ns); one core {1000 * s['median_window_s_1_core']:.0f} ms a window{two}"
        )


def _profile(m):
    print("\n== rate model: CPU time per stage, one thread (s per frame, share) ==")
    if "error" in m:
        print(f"  ERROR {m['error']}")
        return
    p = m["result"]
    print(f"  total {p['total_s_per_frame']:.3f} s per frame over {len(p['inputs'])} frames   [{_load(m)}]")
    for k, v in p["stages_s_per_frame"].items():
        print(f"  {k:52s} {v:7.3f} s  {100 * p['shares'][k]:5.1f} %")


def print_summary(merged: dict, measured: dict) -> None:
    """Tables of the sections measured in this run."""
    for name, sec in measured.items():
        data = sec["data"]
        if name == "calibrate" and "result" in data:
            c = data["result"]["median_s"]
            print(
                f"\n== calibration: scipy.ndimage.correlate 321x481 * 49x49: {c:.3f} s -> authors' frame "
                f"{AUTHORS_CORRELATES_PER_FRAME * c:.0f} s   [{_load(data)}]"
            )
        elif name == "frames":
            _frames(data)
        elif name == "dvs":
            _per_window(f"dvs.es 85 ms windows ({data.get('windows_in_recording')} in the recording)", data)
        elif name == "synthetic":
            _synthetic(data)
        elif name == "throughput":
            _throughput(data)
        elif name == "stream":
            _stream(data)
        elif name == "profile" and data:
            _profile(data)


def plot_scaling(merged: dict, path) -> bool:
    """Time per synthetic window against event count, one line per engine,
    with its least-squares fit; written to ``path`` (PNG). False if no data."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    data = merged.get("sections", {}).get("synthetic", {}).get("data", {})
    series = {eng: m for eng, m in data.items() if isinstance(m, dict) and m.get("result")}
    if not series:
        return False
    fig = Figure(figsize=(6.4, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for eng, m in series.items():
        n = [r["n_events"] for r in m["result"]]
        t = [r["median_s"] for r in m["result"]]
        (line,) = ax.plot(n, t, "o", label=eng)
        fit = m.get("scaling")
        if fit:
            xs = [min(n) * (max(n) / min(n)) ** (i / 40) for i in range(41)]  # a line is curved on log axes
            ax.plot(
                xs,
                [(fit["fixed_ms"] + fit["slope_us_per_event"] * x / 1e3) / 1e3 for x in xs],
                "-",
                color=line.get_color(),
                alpha=0.5,
                label=f"{eng} fit: {fit['fixed_ms']:.0f} ms + {fit['slope_us_per_event']:.1f} us/event",
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("events in the 85 ms window")
    ax.set_ylabel("wall time per window (s)")
    ax.set_title("time per synthetic 320 x 240 window (median of repeats)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True
