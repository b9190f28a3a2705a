"""Make the DAVIS346 test recordings of this folder with iniVation's own writer.

    pip install dv-processing      # (not a dependency of snn-fg: only this script needs it)
    python tests/data/make_davis346_disc.py

Writes, with ``dv_processing.io.MonoCameraWriter`` (the writer of iniVation's
DV software, so that the reader is tested on files it did not write itself):

* ``davis346_disc.aedat4``: :func:`snn_fg.frames.scenes.davis_disc_recording`,
  a light disc seen through the iCub's microsaccade for 400 ms: its events
  and an APS frame every 40 ms, interleaved in time order as a camera writes
  them (the tests know its truth: the disc);
* ``davis346_roi_frames.aedat4``: its first 30 ms of events, with two frames
  of a 173 x 130 region of interest (another size than the event sensor);
* ``davis346_no_frames.aedat4``: its first 30 ms of events, and no frame stream.

The files are committed (about 200 KB together), so that the tests need
neither dv-processing nor the time to simulate the scene; this script says how
they were made.
"""

from __future__ import annotations

import datetime
from pathlib import Path

import dv_processing as dv
import numpy as np

from snn_fg.frames.scenes import DAVIS346_SHAPE, davis_disc_recording

HERE = Path(__file__).resolve().parent
#: the events of the two small files: the first 30 ms
SHORT_US = 30_000


def _store(events) -> dv.EventStore:
    store = dv.EventStore()
    for x, y, t, p in zip(
        events["x"].tolist(), events["y"].tolist(), events["t"].tolist(), events["p"].tolist(), strict=True
    ):
        store.push_back(t, x, y, bool(p))
    return store


def _frame(image, t_start_us: int, exposure_us: int, position=(0, 0)) -> dv.Frame:
    """A dv Frame whose exposure starts at ``t_start_us`` (dv-processing's timestamp is the exposure's start)."""
    frame = dv.Frame(t_start_us, image)
    frame.exposure = datetime.timedelta(microseconds=exposure_us)
    frame.positionX, frame.positionY = position
    return frame


def write(path: Path, config, events, frames=()) -> Path:
    """``events`` and ``frames`` (``(t, dv.Frame)``) into ``path``, in time order."""
    writer = dv.io.MonoCameraWriter(str(path), config)
    done = 0
    for t, frame in frames:
        upto = int(np.searchsorted(events["t"], t, side="right"))
        if upto > done:
            writer.writeEvents(_store(events[done:upto]))
            done = upto
        writer.writeFrame(frame)
    if done < len(events):
        writer.writeEvents(_store(events[done:]))
    del writer  # (closes the file)
    return path


def main() -> None:
    h, w = DAVIS346_SHAPE
    rec = davis_disc_recording()
    ev = rec.recording.events
    frames = [
        (f.exposure_us[0], _frame(f.image, f.exposure_us[0], f.exposure_us[1] - f.exposure_us[0])) for f in rec.frames
    ]
    write(HERE / "davis346_disc.aedat4", dv.io.MonoCameraWriter.DAVISConfig("DAVIS346_synthetic", (w, h)), ev, frames)

    short = ev[ev["t"] < ev["t"][0] + SHORT_US]
    roi = dv.io.MonoCameraWriter.Config("DAVIS346_synthetic")
    roi.addEventStream((w, h))
    roi.addFrameStream((w // 2, h // 2))
    t0 = int(short["t"][0])
    corner = [
        (
            t0 + k * 10_000,
            _frame(
                rec.frames[0].image[h // 4 : h // 4 + h // 2, w // 4 : w // 4 + w // 2].copy(),
                t0 + k * 10_000,
                4_000,
                (w // 4, h // 4),
            ),
        )
        for k in range(2)
    ]
    write(HERE / "davis346_roi_frames.aedat4", roi, short, corner)
    write(
        HERE / "davis346_no_frames.aedat4", dv.io.MonoCameraWriter.EventOnlyConfig("DAVIS346_synthetic", (w, h)), short
    )
    for name in ("davis346_disc", "davis346_roi_frames", "davis346_no_frames"):
        print(f"{name}.aedat4: {(HERE / f'{name}.aedat4').stat().st_size:,} bytes")


if __name__ == "__main__":
    main()
