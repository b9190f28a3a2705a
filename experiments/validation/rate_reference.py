"""Agreement of the rate model with the authors' published outputs, and scores
on the built-in synthetic scenes. Writes experiments/results/rate_reference.json.

    python -m experiments.validation.rate_reference
"""

from __future__ import annotations

import numpy as np

from experiments.common import Run, dataset, save_json
from snn_fg.events import image_to_frame
from snn_fg.frames import scenes
from snn_fg.models.rate.edfg import run_edfg, run_edfg_state
from snn_fg.models.rate.fbfg import run_fbfg
from snn_fg.scoring.metrics import angle_difference_deg, grouping_peak_inside, pearson, truth_scores


def main():
    run = Run()
    out = {"bsds": [], "discs": [], "occlusion": {}}
    for p in sorted(dataset("bsds-edfg").glob("*.npz")):
        ref = np.load(p)
        st = run_edfg_state(ref["pos"], ref["neg"])
        mag = np.hypot(ref["fg_x"], ref["fg_y"])
        sel = mag > 0.01 * mag.max()
        row = {
            "frame": p.stem,
            **{f"r_{k}": pearson(getattr(st, k), ref[k]) for k in ("grouping", "fg_x", "fg_y")},
            "orientation_equal": float(np.mean((st.winner * np.pi / 8).astype(np.float32) == ref["orientation"])),
            "median_angle_diff_deg": float(
                np.median(angle_difference_deg(st.fg_x, st.fg_y, ref["fg_x"], ref["fg_y"])[sel])
            ),
            "max_abs_diff_grouping": float(np.abs(st.grouping - ref["grouping"]).max()),
        }
        out["bsds"].append(row)
        print(" ".join(f"{k}={v:.7g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()), flush=True)
    for radius in (16, 28, 40, 64):
        for light in (True, False):
            sc = scenes.disc(radius, light)
            pos, neg = image_to_frame(sc.image, threshold=0.10)
            m = run_edfg(pos, neg)
            f = run_fbfg(sc.image)
            row = {
                "scene": sc.name,
                "rate": truth_scores(m.fg_x, m.fg_y, sc),
                "rate_peak_inside": grouping_peak_inside(m.grouping, sc),
                "fbfg": truth_scores(f.fg_x, f.fg_y, sc),
                "fbfg_peak_inside": grouping_peak_inside(f.grouping, sc),
            }
            out["discs"].append(row)
            print(
                f"{sc.name:18s} rate {row['rate']['frac_within_45']:.3f} / {row['rate']['median_err_deg']:.1f} deg "
                f"peak-in {row['rate_peak_inside']}   fbfg {row['fbfg']['frac_within_45']:.3f} / "
                f"{row['fbfg']['median_err_deg']:.1f} deg peak-in {row['fbfg_peak_inside']}",
                flush=True,
            )
    sc = scenes.occlusion()
    pos, neg = image_to_frame(sc.image, threshold=0.10)
    m = run_edfg(pos, neg)
    f = run_fbfg(sc.image)
    out["occlusion"] = {
        "rate": scenes.shared_border_ownership(sc, m.fg_x, m.fg_y, 1, 0),
        "fbfg": scenes.shared_border_ownership(sc, f.fg_x, f.fg_y, 1, 0),
    }
    print("occlusion: fraction of the shared border owned by the occluder (fraction, pixels):", out["occlusion"])
    save_json("rate_reference", {**out, "run": run.record()})


if __name__ == "__main__":
    main()
