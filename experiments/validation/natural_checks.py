"""Is the natural-scene variant still a figure-ground model on inputs with an
analytic answer? Discs, the demo scene's square and the plane of dvs.es, for
its rate and spiking forms (``natural_scenes --checks`` runs these).

    python -m experiments.validation.natural_checks

* discs of radius 16, 24, 32, 48 and 64 px, light on dark and dark on light
  (shift4 events at C = 0.10): the share of rim vectors within 45 degrees of
  the inward normal, and whether the grouping peak lies inside;
* the demo scene: the share of the square's outline against the background
  whose vectors point into the square (within 90 and within 45 degrees);
* dvs.es from 100 ms, 85 ms windows: per window whether the grouping peak lies
  on the plane and the share of outline vectors pointing inward (the spiking
  form as one network over the recording, as ``snn-fg run`` runs it).
"""

from __future__ import annotations

from experiments.common import DVS_FROM_MS, Run, describe, markdown_table, save_results
from snn_fg.events.cutter import WINDOW_MS

RADII = (16, 24, 32, 48, 64)
FORMS = {"natural": {}, "natural-spiking": {"backend": "fast"}}


def _model(name):
    from snn_fg.models import get_model

    return get_model(name, **FORMS[name])


def disc_checks(name) -> list[dict]:
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc
    from snn_fg.models import Still
    from snn_fg.scoring.metrics import grouping_peak_inside, truth_scores

    model, out = _model(name), []
    for radius in RADII:
        for light in (True, False):
            scene = disc(radius=radius, light_on_dark=light)
            maps = model.run_still(Still(*image_to_frame(scene.image)))
            t = truth_scores(maps.fg_x, maps.fg_y, scene)
            out.append(
                {
                    "radius": radius,
                    "light_on_dark": light,
                    "within45": t["frac_within_45"],
                    "coverage": t["coverage"],
                    "peak_inside": grouping_peak_inside(maps.grouping, scene),
                }
            )
    return out


def demo_check(name) -> dict:
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import demo, shared_border_ownership
    from snn_fg.models import Still

    scene = demo()
    maps = _model(name).run_still(Still(*image_to_frame(scene.image)))
    side, n = shared_border_ownership(scene, maps.fg_x, maps.fg_y, front=0, back=-1)
    within45, _ = shared_border_ownership(scene, maps.fg_x, maps.fg_y, front=0, back=-1, tol_deg=45.0)
    return {"square_outline_owned": side, "square_outline_within45": within45, "vectors": n}


def dvs_check(name, recording) -> list[dict]:
    from snn_fg.events import iter_windows
    from snn_fg.scoring.metrics import grouping_peak
    from snn_fg.scoring.outline import filled_outline, outline_scores

    windows = list(iter_windows(recording, window_ms=WINDOW_MS, start_ms=DVS_FROM_MS))
    out = []
    for w, maps in _model(name).run_windows(windows):
        region = filled_outline(w.pos | w.neg)
        r, c = grouping_peak(maps.grouping)
        o = outline_scores(maps.fg_x, maps.fg_y, region)
        out.append(
            {
                "t_start_ms": w.t_start_us / 1000,
                "peak_on_plane": bool(region[r, c]),
                "inward": o["inward"],
                "within45": o["within45"],
                "vectors": o["vectors"],
            }
        )
    return out


def checks() -> dict:
    """Every check for both forms; dvs.es only when the dataset ``events`` is present."""
    from snn_fg import datasets

    recording = datasets.find("events", "dvs.es")
    out = {}
    for name in FORMS:
        out[name] = {"discs": disc_checks(name), "demo": demo_check(name)}
        if recording is not None:
            out[name]["dvs"] = dvs_check(name, recording)
    return out


def checks_markdown(c: dict) -> list[str]:
    def row(name, r):
        d, dv = r["discs"], r.get("dvs", [])
        inward = [w["inward"] for w in dv]
        return [
            name,
            f"{min(x['within45'] for x in d):.3f}",
            f"{sum(x['peak_inside'] for x in d)}/{len(d)}",
            f"{r['demo']['square_outline_owned']:.3f} / {r['demo']['square_outline_within45']:.3f}",
            f"{sum(w['peak_on_plane'] for w in dv)}/{len(dv)}" if dv else "-",
            f"{min(inward):.2f}-{max(inward):.2f}" if dv else "-",
        ]

    return ["## Synthetic scenes and dvs.es", ""] + markdown_table(
        [
            "form",
            "discs r 16-64, both polarities: within 45 deg (min)",
            "grouping peak inside",
            "demo square: outline owned by the square (within 90 / 45 deg)",
            "dvs.es from 100 ms: plane found",
            "inward share (min-max)",
        ],
        [row(name, r) for name, r in c.items()],
    )


def main():
    run = Run()
    c = checks()
    record = {"forms": c, "run": run.record()}
    save_results(
        "natural_checks",
        record,
        [
            "# The natural-scene variant on inputs with an analytic answer",
            "",
            describe(record["run"]),
            "",
            *checks_markdown(c),
        ],
    )


if __name__ == "__main__":
    main()
