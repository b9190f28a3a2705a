"""``snn-fg run``'s model options: the flags of the parameters, recordings, the
spiking, rate and frame-based models (:data:`RUN_OPTIONS`), which of them
apply to which model and input (:func:`refused_options`), and the model they
ask for (:func:`chosen_model`)."""

from __future__ import annotations

import argparse

from ..backends import DEFAULT_BACKEND, backend_names
from ..errors import InputError
from ..events.cutter import WINDOW_MS
from ..events.esim import THRESHOLD
from ..frames.pool import MAPS_GRIDS
from ..frames.still import KIND_NAMES, image_scale_refusal
from ..lowering.unroll import INSTANTIATE
from ..models import MODELS, get_model
from ..models.interface import SPIKE_INPUTS
from ..models.spiking.options import FRAME_DURATION_MS, READOUT_LAG_MS
from ..network.graph import HELD_CODINGS, INPUT_CODINGS
from ..network.recipes import INPUT_REFRACTORY_MS, POOL, TIME_STEPS_TEXT, model_params_of
from ..params import EDGE_OPERATORS, LOWER, NATURAL_PARAMS, RUN_PARAMS, ModelParams
from .options import iterations_bar, number

MODEL_PARAMS = RUN_PARAMS
#: how a recording is cut into windows (snn_fg.events.iter_windows)
WINDOW_OPTIONS = ("window_ms", "start_ms", "stride_ms", "max_windows", "denoise_us", "refractory_us")
#: options that only a recording uses
RECORDING_OPTIONS = WINDOW_OPTIONS + (
    "end_ms",
    "readout_lag_ms",
    "readout_ms",
    "carry_state",
    "window_clock",
    "input_coding",
    "save_spikes",
    "resume",
)
#: spiking options for one frame that a recording (one continuous run) does not use
FRAME_ONLY_OPTIONS = ("duration_ms", "settle_ms", "seed", "spike_input")

_DEFAULTS = ModelParams()


def _default(name: str) -> str:
    """A parameter's default as the help gives it: the paper's, and the natural model's where it differs."""
    paper, natural = getattr(_DEFAULTS, name), getattr(NATURAL_PARAMS, name)
    return f"{paper:g}" + ("" if natural == paper else f"; natural: {natural:g}")


#: (group title, ((flag, type, lower bound, strictly above it, help), ...)); defaults in brackets
RUN_OPTIONS = (
    (
        "model parameters (defaults: the paper's)",
        (
            (
                "--network",
                None,
                None,
                None,
                "a network by name (default, the one used when none is given; compact, the deployment form, "
                "docs/model.md) or a stored description (FILE.json, see networks/); "
                "its model parameters replace the options below, for the rate and "
                "the spiking model",
            ),
            ("--levels", int, *LOWER["levels"], f"pyramid levels ({_default('levels')})"),
            ("--n-ori", int, *LOWER["n_ori"], f"orientations per half-turn ({_default('n_ori')})"),
            ("--r0", float, *LOWER["r0"], f"grouping radius in px: sets the object size grouped ({_default('r0')})"),
            ("--iterations", int, *LOWER["iterations"], f"grouping/feedback iterations ({_default('iterations')})"),
            ("--alpha", float, *LOWER["alpha"], f"feedback gain ({_default('alpha')})"),
            ("--w-inh", float, *LOWER["w_inh"], f"opposite border-ownership inhibition ({_default('w_inh')})"),
            (
                "--side-cue",
                float,
                *LOWER["side_cue"],
                f"gain of the side cue, the busier side within {_DEFAULTS.side_cue_radius:g} px "
                f"({_default('side_cue')})",
            ),
        ),
    ),
    (
        "recordings (not for frames or images)",
        (
            ("--window-ms", float, 0, True, f"window length ({WINDOW_MS:g}, the iCub microsaccade period)"),
            ("--start-ms", float, 0, False, "start of the first window, ms after the first event (0)"),
            ("--stride-ms", float, 0, True, "window stride (the window length)"),
            ("--end-ms", float, 0, True, "end of the last window, ms after the first event (the recording's end)"),
            ("--max-windows", int, 1, False, "stop after this many windows (all)"),
            ("--denoise-us", int, 0, True, "tonic Denoise filter time in us (off)"),
            ("--refractory-us", int, 0, True, "tonic RefractoryPeriod in us (off)"),
        ),
    ),
    (
        "spiking model",
        (
            (
                "--backend",
                None,
                None,
                None,
                f"simulator: {', '.join(backend_names())} ({DEFAULT_BACKEND}; "
                "the one used is recorded in the maps' params)",
            ),
            (
                "--duration-ms",
                float,
                0,
                True,
                f"frames and images: simulated time ({FRAME_DURATION_MS:g}; a recording runs as long as its windows)",
            ),
            (
                "--settle-ms",
                float,
                0,
                False,
                "frames and images: spikes before this time are not counted (half of --duration-ms)",
            ),
            (
                "--dt-ms",
                float,
                0,
                True,
                f"simulation time step ({TIME_STEPS_TEXT}; 1 "
                "ms on the default network takes about 3/4 of the time and moves the maps "
                "of natural images by 5-14 deg: experiments/results/spiking_dt.md)",
            ),
            (
                "--seed",
                int,
                0,
                False,
                "frames and images: seed of the input spike phases (0); recordings: of the held sources' "
                "phases, with --input-coding window or sliding only",
            ),
            (
                "--spike-input",
                SPIKE_INPUTS,
                None,
                None,
                "images: regular trains at every event pixel, or the "
                "simulated camera's events with their timing (regular)",
            ),
            (
                "--feedback",
                ("on", "off"),
                None,
                None,
                "off: remove the feedback onto border-ownership cells, the model's ablation (on)",
            ),
            (
                "--readout-lag-ms",
                float,
                0,
                False,
                f"recordings: read each window from the spikes this much later ({READOUT_LAG_MS:g})",
            ),
            (
                "--readout-ms",
                float,
                0,
                True,
                "recordings: count each window's spikes over the last this many ms of its read-out span "
                "only, once the network has settled on it (the whole window)",
            ),
            (
                "--window-clock",
                ("on", "off"),
                None,
                None,
                "recordings: fire the network's window clock as each window "
                "starts (where windows overlap, once every window length), so "
                "that its grouping cells compete afresh (off: the network "
                "carries its state into the next window) (on)",
            ),
            (
                "--input-coding",
                INPUT_CODINGS,
                None,
                None,
                "recordings: how events become input spikes: events, each a spike in its time step, through the "
                f"network's input refractory period (the compact network's {INPUT_REFRACTORY_MS:g} ms); "
                "window, each pixel holds its last event's polarity in the window, firing at the input "
                "rate, which builds the rate model's event frame as the events arrive; sliding, the same "
                "hold kept for one window's length after each event, not cleared as a window starts "
                "(--seed sets the phases) (the network's own: events)",
            ),
            (
                "--instantiate",
                INSTANTIATE,
                None,
                None,
                "cells to create: those this input can use, or every "
                "cell of the network (the backend's choice: brian2 input, "
                "fast and loihi2 all)",
            ),
            (
                "--save-spikes",
                True,
                None,
                None,
                "recordings: also keep each window's spike count of every cell that "
                "fired (about 2 MB a dvs.es window; a frame always keeps them)",
            ),
        ),
    ),
    (
        "maps (rate and spiking models)",
        (
            (
                "--maps-grid",
                MAPS_GRIDS,
                None,
                None,
                "where the maps are read out on a network that pools its input (the compact network's "
                f"{POOL} x {POOL} blocks): on the sensor's pixels, each event pixel's vector turned onto its own "
                "edge, or "
                "on the network's blocks, a ninth of the pixels to decode and store (what a live run with a "
                "short --hop-ms can afford) (sensor)",
            ),
        ),
    ),
    (
        "rate model",
        (
            (
                "--carry-state",
                ("on", "off"),
                None,
                None,
                "recordings: start each window's grouping and feedback where "
                "the previous window's stopped, as a network that is never "
                "reset would (off: each window afresh, the paper's model)",
            ),
        ),
    ),
    (
        "frame-based model",
        (
            (
                "--edge-operator",
                EDGE_OPERATORS,
                None,
                None,
                "simple cells' edge operator: gaussian (a "
                "Gaussian-derivative stand-in) or corf (Hu et al.'s "
                "CORF push-pull, slower) (gaussian)",
            ),
        ),
    ),
)


def add_option_groups(parser, hidden=()) -> None:
    """The groups of :data:`RUN_OPTIONS` on ``snn-fg run``'s parser; the options ``hidden`` (their
    ``dest`` names) are parsed but left out of ``--help``, for a command that refuses them with its reason."""
    for title, options in RUN_OPTIONS:
        g = parser.add_argument_group(title)
        for flag, kind, lo, strict, text in options:
            text = argparse.SUPPRESS if flag[2:].replace("-", "_") in hidden else text
            if kind is True:
                g.add_argument(flag, action="store_const", const=True, help=text)
            elif isinstance(kind, tuple):
                g.add_argument(flag, choices=kind, help=text)
            else:
                g.add_argument(flag, type=number(kind, lo, strict) if kind else None, help=text)


def refused_options(args, kind) -> list[tuple[str, str]]:
    """``(flag, why it does not apply)`` for every given option the run would ignore."""
    model = MODELS[args.model]
    given = lambda k: getattr(args, k) is not None  # noqa: E731
    refused = []
    takers: dict[str, list[str]] = {}  # an option the chosen model does not take -> the models that do
    for other in MODELS.values():
        for k in other.options:
            if k not in model.options and k != "network" and given(k):
                takers.setdefault(k, []).append(other.name)
    for k, names in takers.items():
        which = f"the {names[0]} model" if len(names) == 1 else f"the {', '.join(names[:-1])} and {names[-1]} models"
        refused.append((k, f"applies to {which} only (--model {names[0]})"))
    named = {k for k, _ in refused}
    if kind != "recording":
        refused += [
            (k, f"applies to event recordings only; {KIND_NAMES[kind]}")
            for k in RECORDING_OPTIONS + ("sensor_size", "chip", "channel")
            if given(k) and k not in named
        ]
    else:
        held = args.input_coding in HELD_CODINGS  # (its held sources' phases are drawn from --seed)
        refused += [
            (k, f"applies to a single frame or image only; {KIND_NAMES[kind]}, run as one continuous network")
            for k in FRAME_ONLY_OPTIONS
            if given(k) and k not in named and not (k == "seed" and held)
        ]
    if getattr(args, "image_scale", None) is not None and kind in ("recording", "frame"):
        refused.append(("image_scale", image_scale_refusal(kind)))
    if args.motion is not None and kind in ("recording", "frame") and model.needs != "image":  # images only
        refused.append(("motion", f"applies to images turned into events only; {KIND_NAMES[kind]}"))
    if getattr(args, "threshold", THRESHOLD) != THRESHOLD and kind in ("recording", "frame"):  # (ignored unsaid)
        refused.append(("threshold", f"applies to images turned into events only; {KIND_NAMES[kind]}"))
    if model.needs == "image":  # the frame-based model: no events, no network
        refused += [
            (k, f"the {model.name} model {why}")
            for k, why in (
                ("motion", "reads the image itself, not events made from it"),
                ("network", "has no network (the event models take one)"),
                ("side_cue", "reads the image itself; the side cue counts events"),
            )
            if given(k)
        ]
    if args.network is not None:
        refused += [
            (k, "a named or stored network (--network) carries its own model parameters")
            for k in MODEL_PARAMS
            if given(k)
        ]
        if model.needs != "image" and model.base_params != ModelParams():  # the natural models
            refused.append(
                (
                    "network",
                    f"the {model.name} model has its own parameters, and a network carries "
                    "others (--model spiking --network runs a network as it is)",
                )
            )
    return refused


def _verb(why: str, n: int) -> str:
    return why if n == 1 else why.replace("applies", "apply", 1)


def chosen_model(args, kind):
    """The model the arguments ask for on an input of ``kind`` (:data:`~snn_fg.frames.still.KIND_NAMES`), refusing
    options that would be ignored (one line naming each with why)."""
    refused = refused_options(args, kind)
    if refused:
        reasons: dict[str, list[str]] = {}
        for k, why in refused:
            reasons.setdefault(why, []).append("--" + k.replace("_", "-"))
        said = "; ".join(f"{', '.join(flags)}: {_verb(why, len(flags))}" for why, flags in reasons.items())
        if any(KIND_NAMES[kind] in why for why in reasons):  # (a refusal that is about the input names it first)
            raise InputError(args.input, said)
        flags, problem = said.split(": ", 1)  # (refused whatever the input: the options are the subject)
        raise InputError(flags, problem)
    given = {k: getattr(args, k) for k in MODEL_PARAMS if getattr(args, k) is not None}
    takes = MODELS[args.model].options
    options = {k: getattr(args, k) for k in takes if getattr(args, k) is not None}
    for k in ("feedback", "carry_state", "window_clock"):
        if k in options:
            options[k] = options[k] == "on"
    params = MODELS[args.model].base_params.replace(**given) if args.network is None else model_params_of(args.network)
    if options.get("maps_grid") == "blocks" and params.input_pool == 1:
        raise InputError(
            args.input,
            "--maps-grid blocks: this network sees every sensor pixel (no input pool), so its maps are on "
            "the sensor's grid already; blocks are for a network that pools its input (--network compact)",
        )
    return get_model(args.model, params, iterations_bar(args.no_progress), **options)


# -- resume: a run continued must be the run it continues ---------------------------------------------------------
#: run options that say how many windows a run goes to: a run continued may go further than the run it
#: continues (a spiking run's windows do not depend on how many follow them: its last one is read out
#: with the events after it, models.spiking.continuous.read_past_the_cut)
WINDOW_LIMITS = ("max_windows", "end_ms")
#: run options that do not change a recording's maps (a run may be continued with others)
_NOT_IN_RUN_KEY = (
    "out",
    "force",
    "resume",
    "no_progress",
    "no_figures",
    "crop",
    "handler",
    "command",
    "interrupted",
    "interrupt_note",
    "workers",
    "scheduler",
)


def run_key(args) -> dict:
    """What a continued run (--resume) must share with the run it continues: a window option given
    at its default counts as not given (``--window-ms 85``, ``--start-ms 0``, a stride of the window's
    length), so that typing a default out continues a run made without it (until 30 Nov: refused)."""
    key = {k: v for k, v in sorted(vars(args).items()) if k not in _NOT_IN_RUN_KEY}
    for name, default in (("window_ms", WINDOW_MS), ("start_ms", 0.0)):
        if key.get(name) is not None and float(key[name]) == default:
            key[name] = None
    window = WINDOW_MS if key.get("window_ms") is None else key["window_ms"]
    if key.get("stride_ms") is not None and float(key["stride_ms"]) == float(window):
        key["stride_ms"] = None
    return key
