"""One measurement, run in its own process so its peak memory is its own.

``python -m experiments.bench.child SPEC_JSON`` prints one JSON line: the
timings of the task described by SPEC (see :func:`run_task`). The parent
(:mod:`experiments.bench.run`) reads the process's peak RSS from ``wait4``.
"""

from __future__ import annotations

import json
import statistics
import sys
import time

import numpy as np

from .inputs import load

AUTHORS_SHAPE = (321, 481)  # the reference frames' size
AUTHORS_KERNEL = 49  # their von Mises kernels at R0 = 8: 49 x 49
# One scipy.ndimage.correlate of a 321 x 481 float64 array with a 49 x 49
# kernel took 1/955 of the authors' frame time, same machine, same hour
# (issue 13); their pipeline is dominated by such calls.
AUTHORS_CORRELATES_PER_FRAME = 955


def correlate_seconds() -> float:
    """Wall time of the calibration call (one scipy.ndimage.correlate)."""
    from scipy import ndimage

    rng = np.random.default_rng(0)
    img = rng.random(AUTHORS_SHAPE)
    ker = rng.random((AUTHORS_KERNEL, AUTHORS_KERNEL))
    t = time.perf_counter()
    ndimage.correlate(img, ker)
    return time.perf_counter() - t


def _model(model: str, backend: str | None, instantiate: str | None = None):
    from snn_fg.models import get_model

    if model != "spiking":
        return get_model(model)
    return get_model("spiking", backend=backend, **({"instantiate": instantiate} if instantiate else {}))


def _runner(mdl, inp):
    """The model on one input. A spiking window runs as a recording of one
    window does (one continuous run, its events made spikes by the network's
    input coding, docs/spiking-network.md, "How events become input spikes";
    the window plus the read-out lag simulated, no replay)."""
    from snn_fg.models import Still

    if inp.events is None:
        frame = Still(inp.pos, inp.neg)
        if mdl.name == "spiking":
            return lambda: _spiking_record(mdl.run_still(frame))
        return lambda: mdl.run_still(frame)
    win = inp.window()
    if mdl.name == "spiking":
        return lambda: _spiking_window(mdl, win)
    return lambda: mdl.run_window(win)


#: engine counters of the last spiking run, reported beside its timing
LAST_RUN: dict = {}


def _spiking_window(mdl, win):
    ((_, maps),) = mdl.run_windows([win])
    return _spiking_record(maps)


def _spiking_record(maps):
    """Keep the run's counters in LAST_RUN (a frame's as well as a window's:
    a row must not carry the warm-up's)."""
    p = maps.params
    sim = p["simulation"]
    LAST_RUN.clear()
    LAST_RUN.update(
        simulated_ms=sim.get("simulated_ms", sim.get("duration_ms")),
        instantiate=sim["instantiate"],
        cells=p["counts"]["total_cells"],
        timings_s=p["timings_s"],
        backend_stats=p.get("backend_stats", {}),
    )
    return maps


def time_model(spec: dict) -> list[dict]:
    """Warm up on ``spec["warmup"]`` (or the first input), then time each input
    ``repeats`` times; with ``calibrate`` the calibration call is timed right
    before each repeat, so each ratio compares two timings taken together."""
    mdl = _model(spec["model"], spec.get("backend"), spec.get("instantiate"))
    inputs = [load(s) for s in spec["inputs"]]
    warm = load(spec["warmup"]) if spec.get("warmup") else inputs[0]
    t = time.perf_counter()
    _runner(mdl, warm)()
    warm_s = time.perf_counter() - t
    rows = []
    for inp in inputs:
        run = _runner(mdl, inp)
        times, cpu, corr = [], [], []
        for _ in range(spec["repeats"]):
            if spec.get("calibrate"):
                corr.append(correlate_seconds())
            c = time.process_time()
            t = time.perf_counter()
            run()
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        # CPU time (all threads of this process) is reported beside wall time:
        # on a shared machine it moves much less with the load.
        row = {
            **inp.describe(),
            "times_s": times,
            "median_s": statistics.median(times),
            "min_s": min(times),
            "cpu_s": cpu,
            "cpu_median_s": statistics.median(cpu),
            "warmup_s": warm_s,
        }
        if LAST_RUN:
            row["spiking_run"] = dict(LAST_RUN)
        if corr:
            ratios = [AUTHORS_CORRELATES_PER_FRAME * c / s for c, s in zip(corr, times, strict=True)]
            row.update(
                correlate_s=corr,
                correlate_median_s=statistics.median(corr),
                authors_frame_s=AUTHORS_CORRELATES_PER_FRAME * statistics.median(corr),
                ratio_vs_authors=statistics.median(ratios),
            )
        rows.append(row)
        print(
            f"  {spec['model']}{'/' + spec['backend'] if spec.get('backend') else ''} {inp.name}: "
            f"{row['median_s']:.3f} s",
            file=sys.stderr,
            flush=True,
        )
    return rows


def run_task(spec: dict):
    if spec["task"] == "model":
        return time_model(spec)
    if spec["task"] == "calibrate":
        times = [correlate_seconds() for _ in range(spec["repeats"])]
        return {"times_s": times, "median_s": statistics.median(times)}
    if spec["task"] == "floor":
        from .floor import measure

        return measure(spec.get("state_mb"))
    if spec["task"] == "profile":
        from .profile_rate import profile

        return profile(spec["inputs"], spec["repeats"])
    raise ValueError(f"unknown task {spec['task']!r}")


if __name__ == "__main__":
    print(json.dumps(run_task(json.loads(sys.argv[1]))))
