"""How close ``--motion paper`` comes to the authors' own event frames (bsds-edfg pos/neg).

    python -m experiments.paper.paper_motion

For each of the six reference frames (dataset ``bsds-edfg``): event pixels (ours, theirs), intersection
over union, recall (share of their event pixels that we also have), polarity
agreement on the shared pixels, for ``paper`` and for the built-in ``shift4``.
Then what separates the two: the share of our event pixels that the authors
kept, against the log-intensity change |delta log I| between the two frames
and the pixel's brightness. Writes experiments/results/paper_motion.json /
.csv and paper_motion.png (the curve, and a crop of both frames).
"""

from __future__ import annotations

import numpy as np

from experiments.common import Run, dataset, save_figure, save_json
from experiments.paper.bsds import write_table

IDS = ("12003", "35070", "105053", "159091", "22090", "41004")
DLOG_BINS = np.array([0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.5, 2.0, 7.0])
CROP = (slice(100, 220), slice(150, 330))
EPS = 1e-3


def frame_scores(pos, neg, ref) -> dict:
    ours, theirs = (pos | neg) > 0, (ref["pos"] | ref["neg"]) > 0
    both = ours & theirs
    agree = ((pos > 0) & (ref["pos"] > 0)) | ((neg > 0) & (ref["neg"] > 0))
    return {
        "ours": int(ours.sum()),
        "theirs": int(theirs.sum()),
        "iou": float(both.sum() / (ours | theirs).sum()),
        "recall": float(both.sum() / theirs.sum()),
        "polarity_agreement": float(agree[both].mean()),
    }


def main():
    from snn_fg.events import image_to_frame
    from snn_fg.events.paper_motion import paper_frames

    frames = dataset("bsds-edfg")
    run = Run()
    rows, dlog, kept, bright = [], [], [], []
    for image_id in IDS:
        ref = np.load(frames / f"{image_id}.npz")
        jpg = frames / "images" / f"{image_id}.jpg"
        for motion in ("paper", "shift4"):
            pos, neg = image_to_frame(jpg, threshold=0.10, motion=motion)
            rows.append({"image_id": image_id, "motion": motion, **frame_scores(pos, neg, ref)})
        f0, f1 = paper_frames(jpg)
        d = np.abs(np.log(f1 + EPS) - np.log(f0 + EPS))
        ev = d >= 0.10
        dlog.append(d[ev])
        kept.append(((ref["pos"] | ref["neg"]) > 0)[ev])
        bright.append(np.maximum(f0, f1)[ev])
    dlog, kept, bright = map(np.concatenate, (dlog, kept, bright))
    curve = []
    for lo, hi in zip(DLOG_BINS[:-1], DLOG_BINS[1:]):
        m = (dlog >= lo) & (dlog < hi)
        dark, light = m & (bright < 0.3), m & (bright >= 0.6)
        curve.append(
            {
                "dlog_lo": float(lo),
                "dlog_hi": float(hi),
                "pixels": int(m.sum()),
                "kept": float(kept[m].mean()) if m.any() else None,
                "kept_dark": float(kept[dark].mean()) if dark.sum() > 20 else None,
                "kept_light": float(kept[light].mean()) if light.sum() > 20 else None,
            }
        )
    written = write_table("paper_motion", rows, run=run.record())
    written.append(save_json("paper_motion_curve", curve))
    written.append(save_figure(figure(curve), "paper_motion"))
    for r in rows:
        print(
            f"{r['image_id']:>7s} {r['motion']:7s} ours {r['ours']:6d} theirs {r['theirs']:6d} IoU {r['iou']:.3f} "
            f"recall {r['recall']:.3f} polarity {r['polarity_agreement']:.3f}"
        )
    for c in curve:
        fmt = lambda v: "-" if v is None else f"{v:.3f}"  # noqa: E731
        print(
            f"|dlog I| {c['dlog_lo']:.2f}-{c['dlog_hi']:.2f}: kept {fmt(c['kept'])} (dark {fmt(c['kept_dark'])}, "
            f"light {fmt(c['kept_light'])}) of {c['pixels']}"
        )
    print(f"runtime {run.seconds:.0f} s; wrote " + ", ".join(str(w.name) for w in written))


def figure(curve):
    from matplotlib.figure import Figure

    from snn_fg.events import image_to_frame
    from snn_fg.results.figures import event_frame_rgb

    fig = Figure(figsize=(15, 3.8))
    ax = fig.add_subplot(1, 3, 1)
    mid = [(c["dlog_lo"] + min(c["dlog_hi"], 3.0)) / 2 for c in curve]
    for key, style, label in (
        ("kept", "o-", "all"),
        ("kept_dark", "v--", "dark (max I < 0.3)"),
        ("kept_light", "^--", "light (max I >= 0.6)"),
    ):
        ax.plot(mid, [np.nan if c[key] is None else c[key] for c in curve], style, label=label)
    ax.set_xlim(0, 2.5)
    ax.set_xlabel("|delta log I| between the two frames (C = 0.10 makes an event from 0.10)")
    ax.set_ylabel("share of our event pixels the authors kept")
    ax.legend(fontsize=8)
    ref = np.load(dataset("bsds-edfg", "12003.npz"))
    pos, neg = image_to_frame(dataset("bsds-edfg", "images", "12003.jpg"), threshold=0.10, motion="paper")
    for k, (title, img) in enumerate(
        (
            ("authors' frame (12003, crop)", event_frame_rgb(ref["pos"], ref["neg"])),
            ("--motion paper, C = 0.10", event_frame_rgb(pos, neg)),
        ),
        start=2,
    ):
        a = fig.add_subplot(1, 3, k)
        a.imshow(img[CROP])
        a.set_title(title, fontsize=10)
        a.axis("off")
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    main()
