"""How much a reference agrees with itself: the baseline a comparison needs.

Two maps that agree on 60 % of their vectors say little until one knows how
far the reference moves on its own. :func:`self_agreement` runs the model
that made a maps file again on the same frames with twice its iterations
and scores the file against that run, window by window (the rate model's
10th iteration is still moving on natural images and settled on most
recordings): what ``snn-fg compare`` prints beside each comparison.

The frames come from the file itself: a recording's run stores each
window's event frame (``event_frame``), and the frame-based model's run on a
DAVIS recording the APS frame each window read (``aps_frame``); a still
input's is made again from the input its parameters name. A model that is
not iterated on a frame here (a spiking run) has no baseline of this kind,
and :func:`self_agreement` says why instead.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import SnnFgError
from ..events.esim import MOTION, THRESHOLD
from ..frames.pool import frame_polarities
from ..params import ModelParams
from ..results.maps import Maps, maps_scale
from .metrics import compare_frame, frame_of

#: models whose maps a second run at twice the iterations can check (they iterate on a frame)
ITERATED_MODELS = ("rate", "natural", "fbfg")


def model_params(params: dict) -> ModelParams:
    """The :class:`~snn_fg.params.ModelParams` recorded in a maps file's ``params``."""
    names = {f.name for f in dataclasses.fields(ModelParams)}
    return ModelParams.from_dict({k: v for k, v in params.items() if k in names})


def model_inputs(m: Maps, windows, needs: str) -> list | str:
    """What the model that made ``m`` read in ``windows`` (``[None]``: ``m`` is one frame), as
    :class:`~snn_fg.frames.still.Still` inputs: each window's event frame, or (``needs="image"``, the
    frame-based model) the APS frame it ran on; ``None`` for a window with nothing to read. A string
    says why they are not to be had."""
    from ..events.images import as_float_image
    from ..frames.still import Still, load_frame  # (an image is turned into events again: the camera simulator)

    if m.fg_x.ndim == 3:
        key = "aps_frame" if needs == "image" else "event_frame"
        frames = m.extra.get(key)
        if frames is None:
            return f"it stores no {key} (a recording's run stores them)"
        if needs == "image":
            index = m.extra["aps_index"]
            return [Still(image=as_float_image(frames[i], grey=False)) if index[i] >= 0 else None for i in windows]
        return [Still(*frame_polarities(frames[i])) if np.any(frames[i]) else None for i in windows]
    source = m.params.get("source") or {}
    if "input" not in source:
        return "its parameters name no input"
    try:
        still, _ = load_frame(
            source["input"],
            needs,
            source.get("threshold", THRESHOLD),
            source.get("motion", MOTION),
            source.get("image_scale"),
        )
    except (SnnFgError, OSError) as exc:
        return f"its input {source['input']} cannot be read again ({exc})"
    now = (still.image if needs == "image" else still.pos).shape[:2]
    if now != m.fg_x.shape:  # (the file changed since the run)
        return (
            f"its input {source['input']} is {now[1]} x {now[0]} now, the run's maps {m.fg_x.shape[1]} x "
            f"{m.fg_x.shape[0]}: not the image it ran on"
        )
    return [still]


def self_agreement(m: Maps, windows, factor: int = 2, progress=None, masks=None) -> list[dict] | str:
    """``m`` (its ``windows``: indices, or ``[None]`` for one frame) against
    its own model run again with ``factor`` times its iterations on the same
    frames: per window, the fraction of shared vectors within 45 degrees,
    their mean angle difference, the grouping r, the share of the longer
    run's vectors that ``m`` has and the number of shared vectors.
    ``masks`` (a boolean map a window, or None): the vectors only on those
    pixels (:func:`~snn_fg.scoring.metrics.compared_pixels`; the grouping
    stays on the whole map). A string says why there is none."""
    model = m.params.get("model")
    if model not in ITERATED_MODELS:
        return f"B comes from the {model or 'unknown'} model, which is not iterated on an event frame here"
    from ..models import MODELS, get_model  # (the rate models' packages compile on first use)

    inputs = model_inputs(m, windows, MODELS[model].needs)
    if isinstance(inputs, str):
        return f"B {inputs}"
    params = model_params(m.params)
    options = {k: m.params[k] for k in MODELS[model].options if k in m.params}
    if m.fg_x.ndim == 3 and maps_scale(m.params) > 1:  # (maps and stored frames on blocks: the frames pooled already)
        params, options = params.replace(input_pool=1), {k: v for k, v in options.items() if k != "maps_grid"}
    longer = get_model(model, params.replace(iterations=max(1, params.iterations) * factor), progress, **options)
    rows = []
    for i, still, keep in zip(windows, inputs, masks or [None] * len(windows), strict=True):
        fx, fy, g = frame_of(m, i)
        if still is None:
            rows.append(None)
            continue
        ref = longer.run_still(still)
        rx, ry = ref.fg_x, ref.fg_y
        if keep is not None:
            fx, fy, rx, ry = (np.where(keep, v, 0) for v in (fx, fy, rx, ry))
        c = compare_frame(fx, fy, g, rx, ry, ref.grouping)
        rows.append(
            {
                "iterations": int(params.iterations),
                "against_iterations": int(params.iterations) * factor,
                "within_45": c["angle_within_45_frac"],
                "mean_deg": c["angle_diff_mean_deg"],
                "grouping_r": c["grouping_pearson_r"],
                "coverage": c["coverage_of_b"],
                "pixels": c["pixels_compared"],
            }
        )
    return rows
