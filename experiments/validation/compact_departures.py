"""Where the compact network parts from its reference: each of its departures on its own (issue 54).

    python -m experiments.validation.compact_departures [--windows 3] [--no-bsds] [--one-at-a-time LEVER ...]

The compact network is the default with the eight levers of
``snn_fg.network.recipes.COMPACT_LEVERS`` applied in order. Each network
here is scored by its still-frame ceiling (``recording_ceiling``: each
window's event frame handed to it as a still input for 400 ms, counted over
200-400 ms) against the rate model on its OWN model parameters (pooled input
and octave levels change them, so the reference changes with them), on the
pixels where both have a vector (within 45 degrees, mean absolute
difference, grouping r, coverage), on ``dvs.es`` and the person recording
and, unless ``--no-bsds``, the six BSDS frames:

* the compact network, and for each lever the compact network with that one
  lever reverted (leave-one-out: the other seven applied, in order);
* with ``--one-at-a-time``: the default network with only the named levers
  applied (``all``: each of them; ``default``: the default network itself).

The input refractory period and the window clock act only on a recording's
events (a still frame's trains are not thinned and its clock never fires),
so the still frames cannot see them: ``--events`` runs the leave-one-out rows
(or ``--only`` these) on ``--windows`` windows of the recordings' events as
they come, against the same references, and writes
``compact_departures_events.{json,md}``.

Beside the scores, each network's size at the iCub's 304 x 240
(``compact_levers.size``: neurons, synapses) and the seconds a still frame
took, so the cost of reverting a lever shows. Rows are written to
``compact_departures.{json,md}`` as they are measured; a run stopped midway
resumes from them (same number of windows). The figure
(``compact_departures.png``) shows the share within 45 degrees per network.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from experiments.common import RESULTS, Run, describe, markdown_table, save_figure, save_results
from experiments.validation.compact_levers import size
from experiments.validation.recording_ceiling import rate_refs, still_maps, still_sets
from experiments.validation.recording_fidelity import scores

NAME = "compact_departures"
#: the compact network's bar against the rate model on its own recipe (issue 54)
BAR = 0.75


def leave_one_out(skip: int):
    """The default recipe with every lever of ``COMPACT_LEVERS`` but the ``skip``-th applied, in order."""
    from snn_fg.network.recipes import COMPACT_LEVERS, RECIPES

    r = RECIPES["default"]
    for k, lever in enumerate(COMPACT_LEVERS):
        if k != skip:
            r = lever.apply(r)
    compact = RECIPES["compact"]
    if (r.params, r.spiking) == (compact.params, compact.spiking):  # (a lever that changes nothing: no row)
        raise ValueError(f"reverting {COMPACT_LEVERS[skip].name!r} leaves the compact recipe unchanged")
    return r


def variants(one_at_a_time) -> list[tuple[str, str, object]]:
    """``(label, kind, Recipe)``: the compact network, each lever reverted, then the default-based rows."""
    from snn_fg.network.recipes import COMPACT_LEVERS, RECIPES

    rows = [("compact", "compact", RECIPES["compact"])]
    rows += [(f"compact without {lv.name}", "leave one out", leave_one_out(k)) for k, lv in enumerate(COMPACT_LEVERS)]
    names = [lv.name for lv in COMPACT_LEVERS] if "all" in one_at_a_time else one_at_a_time
    if "default" in one_at_a_time:
        rows.append(("default", "default", RECIPES["default"]))
    for lever in COMPACT_LEVERS:
        if lever.name in names:
            rows.append((f"default with {lever.name}", "one at a time", lever.apply(RECIPES["default"])))
    return rows


def measure(label: str, kind: str, recipe, sets: dict, refs: dict) -> dict:
    """One network's still ceiling on each set against the rate model on its own parameters, and its size."""
    row = {"label": label, "kind": kind, "size": size(recipe), "sets": {}}
    for name, wins in sets.items():
        maps, per_window_s = still_maps(wins, None, params=recipe.params, spiking=recipe.spiking)
        row["sets"][name] = {**scores(maps, refs[name]), "s_per_window": per_window_s}
        r = row["sets"][name]
        print(f"{label}, {name}: {r['within_45']:.3f} within 45 deg, {per_window_s:.1f} s a frame", flush=True)
    return row


def cells(row: dict, names) -> list[str]:
    s = row["size"]
    out = [row["label"], f"{s['neurons'] / 1e6:.2f} M", f"{s['synapses'] / 1e6:.0f} M"]
    for name in names:
        r = row["sets"].get(name)
        if r is None:
            out.append("")
            continue
        per = r["within_45_per_window"]
        out.append(
            f"{r['within_45']:.1%} ({np.nanmin(per):.0%}-{np.nanmax(per):.0%}) / {r['mean_abs_deg']:.1f}° / "
            f"{r['grouping_r_mean']:.2f} / {r['coverage']:.0%} / {r['s_per_window']:.1f} s"
        )
    return out


def lines_of(record: dict) -> list[str]:
    names = record["sets"]
    head = [
        "# Where the compact network parts from its reference: each departure on its own",
        "",
        describe(record["run"]),
        "",
        f"Still frames ({record['windows']} windows of each recording, 85 ms; the six BSDS frames where given) "
        "presented for 400 ms, counted over 200-400 ms, against the rate model on each network's own model "
        "parameters; pixels where both have a vector. Size at 304 x 240. Each cell: within 45° (pooled; per "
        "window) / mean abs / grouping r (mean over frames) / coverage / seconds a frame.",
        "",
    ]
    header = ["network", "neurons", "synapses", *(f"{n}" for n in names)]
    return head + markdown_table(header, (cells(r, names) for r in record["rows"]))


def figure(record: dict):
    import matplotlib

    matplotlib.use("Agg")  # (an experiment script, never imported by the package)
    import matplotlib.pyplot as plt

    rows, names = record["rows"], record["sets"]
    fig, axes = plt.subplots(1, len(names), figsize=(4.6 * len(names), 0.38 * len(rows) + 1.6), sharey=True)
    y = np.arange(len(rows))[::-1]
    base = next(r for r in rows if r["kind"] == "compact")
    for ax, name in zip(np.atleast_1d(axes), names):
        vals = [r["sets"].get(name, {}).get("within_45", np.nan) for r in rows]  # (nan: not measured)
        colors = ["0.4" if r["kind"] == "compact" else "C0" if r["kind"] == "leave one out" else "C1" for r in rows]
        ax.barh(y, vals, color=colors)
        ax.axvline(base["sets"][name]["within_45"], color="0.4", ls=":", label="compact")
        if not name.startswith("BSDS"):  # (the bar is the recordings')
            ax.axvline(BAR, color="C3", ls="--", label=f"bar {BAR:.0%}")
        ax.set_xlim(0.4, 1.0)
        ax.set_title(f"{name}: within 45° of the rate model", fontsize=9)
        ax.set_xlabel("share of shared vector pixels")
    ax0 = np.atleast_1d(axes)[0]
    ax0.set_yticks(y, [r["label"] for r in rows], fontsize=8)
    ax0.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    return fig


def events_rows(labels, n: int) -> tuple[dict, list[str]]:
    """The same networks on the recordings' events as they come (``events`` coding, one continuous run of
    ``n`` windows), against the rate model on each one's own parameters: what the input refractory period
    and the window clock act on, which a still frame never meets. Plus ``dvs.es``'s outline inward."""
    from experiments.validation.recording_fidelity import inward, windows_of
    from snn_fg.models.spiking import run_spiking_windows

    wins = {name: windows_of(name, n) for name in ("dvs_biplane", "person")}
    out, rows, refs_by_params = {}, [], {}
    for label, _, recipe in variants([]):
        if labels and label not in labels:
            continue
        key = repr(recipe.params)  # (the levers of the spiking constants share the rate model's maps)
        refs = refs_by_params[key] = refs_by_params.get(key) or rate_refs(wins, recipe.params)
        out[label], cells_ = {}, [label]
        for name, ws in wins.items():
            maps = run_spiking_windows(ws, params=recipe.params, spiking=recipe.spiking, progress=False)
            r = out[label][name] = scores(maps, refs[name])
            inw = ""
            if name == "dvs_biplane":
                r["inward"] = inward(maps, ws)
                inw = f" / inward {np.median(r['inward']):.2f}"
            cells_.append(f"{r['within_45']:.1%} / {r['mean_abs_deg']:.1f}° / {r['coverage']:.0%}{inw}")
        rows.append(cells_)
        print(" | ".join(cells_), flush=True)
    header = ["network", *(f"{k} ({n} windows, events): within 45° / mean abs / coverage" for k in wins)]
    return out, markdown_table(header, rows)


def stored_record(run, windows: int, sets: dict, rows: list, earlier: list) -> tuple[dict, list[str]]:
    record = {"run": run.record(), "earlier_runs": earlier, "windows": windows, "sets": list(sets), "rows": rows}
    lines = lines_of(record)
    lines[2:3] = [f"{describe(r)} (an earlier part of the run)" for r in earlier] + lines[2:3]
    return record, lines


def main():
    from snn_fg.network.recipes import COMPACT_LEVERS

    choices = ["all", "default", *(lv.name for lv in COMPACT_LEVERS)]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=3, help="windows per recording (3)")
    ap.add_argument("--no-bsds", action="store_true", help="leave out the six BSDS frames (their cells stay blank)")
    ap.add_argument("--one-at-a-time", nargs="*", choices=choices, default=[], metavar="LEVER", help=str(choices))
    ap.add_argument("--only", nargs="+", metavar="LABEL", help="measure only these rows (labels as in the table)")
    ap.add_argument("--fresh", action="store_true", help="do not resume from a stored record")
    ap.add_argument("--events", action="store_true", help="the leave-one-out rows on the events (events_rows)")
    ap.add_argument("--figure", action="store_true", help="only draw the figure again from the stored record")
    a = ap.parse_args()
    if a.figure:
        save_figure(figure(json.loads((RESULTS / f"{NAME}.json").read_text())), NAME)
        return
    run = Run()
    if a.events:
        record, lines = events_rows(a.only, a.windows)
        head = ["# The compact network's departures on the recordings' events", "", describe(run.record()), ""]
        save_results(f"{NAME}_events", {"run": run.record(), "windows": a.windows, "rows": record}, head + lines)
        return
    sets = still_sets(a.windows)
    measured = {k: v for k, v in sets.items() if not (a.no_bsds and k.startswith("BSDS"))}
    stored = RESULTS / f"{NAME}.json"
    done, earlier = {}, []
    if stored.exists() and not a.fresh:
        old = json.loads(stored.read_text())
        if old["windows"] == a.windows:
            done, earlier = {r["label"]: r for r in old["rows"]}, [*old.get("earlier_runs", []), old["run"]]
            print(f"resuming: {len(done)} rows from {stored}", flush=True)
    refs_by_params, rows = {}, []
    for label, kind, recipe in variants(a.one_at_a_time):
        if label in done:
            rows.append(done.pop(label))
            continue
        if a.only and label not in a.only:
            continue
        key = repr(recipe.params)
        if key not in refs_by_params:
            refs_by_params[key] = rate_refs(measured, recipe.params)
        rows.append(measure(label, kind, recipe, measured, refs_by_params[key]))
        save_results(NAME, *stored_record(run, a.windows, sets, rows + list(done.values()), earlier))
    record, lines = stored_record(run, a.windows, sets, rows + list(done.values()), earlier)
    save_results(NAME, record, lines)
    save_figure(figure(record), NAME)


if __name__ == "__main__":
    main()
