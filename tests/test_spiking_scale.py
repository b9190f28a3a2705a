"""experiments.bench.spiking_scale: its page from the rows its child processes report."""

from experiments.bench.spiking_scale import markdown

RUN = {"commit": "0123456789", "command": "python -m experiments.bench.spiking_scale", "date": "d", "seconds": 1.0}
RUN |= {"processor": "", "load_before": [0.0] * 3, "load_after": [0.0] * 3}


def _row(synapses_in):
    population = {"role": "simple", "level": 1, "cells": 10, "mean_rate_hz": 2.0, "synapses_in": synapses_in}
    return {
        "frame": "1",
        "backend": {"name": "fast"},
        "instantiate": "input",
        "counts": {"total_cells": 10, "total_synapses": None},
        "backend_stats": {"synaptic_events_total": 5, "spikes": 3},
        "timings_s": {"run": 0.5},
        "process_wall_s": 1.0,
        "peak_rss_mb": 100.0,
        "load_before": 0.0,
        "load_after": 0.0,
        "populations": {"simple_1": population},
    }


def _population_line(synapses_in) -> str:
    page = "\n".join(markdown([_row(synapses_in)], RUN))
    return next(line for line in page.splitlines() if line.startswith("simple_1 "))


def test_an_engine_that_makes_no_synapses_has_a_dash_in_the_population_table():
    assert _population_line(None).split() == ["simple_1", "simple", "1", "10", "2.0", "-"]
    assert _population_line(7).split() == ["simple_1", "simple", "1", "10", "2.0", "7"]
