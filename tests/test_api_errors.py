"""Wrong input to the Python API is one error naming the argument and the
problem, raised where it comes in (snn_fg.errors' types), not a numpy,
TypeError or AttributeError from deep inside a model (issue B)."""

import inspect

import numpy as np
import pytest

from snn_fg.errors import InputError, ParameterError
from snn_fg.events import image_to_frame, iter_windows
from snn_fg.frames.scenes import disc
from snn_fg.models import Still, get_model
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.models.rate.fbfg import run_fbfg
from snn_fg.models.spiking import run_spiking
from snn_fg.params import ModelParams


@pytest.fixture(scope="module")
def frame():
    return image_to_frame(disc(12).image)


def test_a_still_whose_frames_differ_in_shape_is_refused_before_the_model_runs(frame):
    pos, neg = frame
    with pytest.raises(InputError, match=r"Still: pos and neg differ in shape: \(64, 64\) vs \(63, 64\)"):
        get_model("rate").run_still(Still(pos, neg[:-1]))
    with pytest.raises(InputError, match="run_edfg: pos and neg differ in shape"):
        run_edfg(pos, neg[:-1])
    with pytest.raises(InputError, match="run_spiking: pos and neg differ in shape"):
        run_spiking(pos, neg[:-1], progress=False)


def test_rgb_frames_a_missing_frame_and_values_outside_0_1_are_refused(frame):
    pos, neg = frame
    rgb = [np.repeat(a[..., None], 3, axis=2) for a in frame]
    with pytest.raises(InputError, match=r"pos has shape \(64, 64, 3\), not 2-D"):
        Still(*rgb)
    with pytest.raises(InputError, match="run_edfg: neg is None"):
        run_edfg(pos, None)
    with pytest.raises(InputError, match=r"pos holds values outside \[0, 1\] \(min 0, max 255\)"):
        run_edfg(pos * 255.0, neg)
    with pytest.raises(InputError, match=r"neg holds values outside \[0, 1\] \(min -1"):
        Still(pos, -neg.astype(np.int8))
    with pytest.raises(InputError, match=r"run_fbfg: image holds values outside \[0, 1\].*divided by 255"):
        run_fbfg(disc(12).image * 255)
    with pytest.raises(InputError, match=r"Still: image has shape \(64, 64, 2\)"):
        Still(image=np.zeros((64, 64, 2)))
    with pytest.raises(InputError, match="give an event frame"):
        Still()


def test_run_windows_refuses_a_path_and_stills_naming_what_to_give(frame):
    for name in ("rate", "spiking"):
        model = get_model(name)
        with pytest.raises(InputError, match=r"dvs.es: run_windows takes windows, not a path: .*iter_windows\("):
            list(model.run_windows("dvs.es"))
        with pytest.raises(InputError, match="item 0 is a Still, not an EventWindow .*run_still"):
            list(model.run_windows([Still(*frame)]))


def test_get_model_refuses_an_unknown_option_and_network_naming_its_own():
    with pytest.raises(ParameterError, match="get_model: model 'spiking' takes no option netwrok .*network, backend"):
        get_model("spiking", netwrok="compact")
    with pytest.raises(InputError, match=r"compactt: neither a network name \(default, compact\)"):
        get_model("spiking", network="compactt")
    assert get_model("spiking", network="compact").params.input_pool == 3  # (the compact network's own params)


def test_get_model_takes_what_snn_fg_run_takes_for_the_rate_model():
    """get_model("rate", network="compact") and get_model("rate", r0=8) were refused, where `snn-fg run
    --model rate --network compact` and `--r0 8` run (a new user's trial from Python, 1 Dec)."""
    from snn_fg.network.recipes import model_params_of

    assert get_model("rate", network="compact").params == model_params_of("compact")
    assert get_model("rate", r0=4, levels=6).params == ModelParams(r0=4, levels=6)
    assert get_model("spiking", r0=4).params.r0 == 4
    with pytest.raises(ParameterError, match="r0: give the model parameters as params=.* or as keywords, and not"):
        get_model("rate", network="compact", r0=4)
    with pytest.raises(ParameterError, match="model 'fbfg' takes no option network"):  # (as the command line)
        get_model("fbfg", network="compact")


def test_float_timestamps_are_refused_as_integer_microseconds():
    ev = np.zeros(3, dtype=[("x", "i2"), ("y", "i2"), ("t", "f8"), ("p", "i1")])
    ev["t"] = [0.000654, 0.001, 0.002]
    with pytest.raises(InputError, match="field t must hold integer microseconds .*multiply by 1e6") as caught:
        next(iter_windows(ev, sensor_size=(10, 10)))
    assert str(caught.value).endswith(", got 0.000654 (at event 0)")  # (a number as written, not np.float64(...))


def test_help_of_still_says_dtype_range_and_shape():
    doc = inspect.getdoc(Still)
    for said in ("H x W", "uint8 or bool", "0 elsewhere", "floats in [0, 1]", "H x W x 3", "row 0 at the top"):
        assert said in doc


def test_wrong_things_handed_to_the_api_are_named_not_tracebacks(frame):
    """A new user's trial from Python (1 Dec): run_still((pos, neg)) was an AttributeError from inside the
    model, get_model(network=1) a TypeError from pathlib, run_live(window_ms="85") a TypeError from its
    warm-up."""
    from snn_fg.models import run_live

    for given in (frame, frame[0]):
        with pytest.raises(InputError, match=r"run_still takes a Still: Still\(pos, neg\) for an event frame"):
            get_model("rate").run_still(given)
    with pytest.raises(InputError, match=r"<int>: a network is a name \(default, compact\)"):
        get_model("spiking", network=1)
    with pytest.raises(ParameterError, match="run_live: window_ms='85' must be a finite number"):
        run_live(get_model("rate"), [], None, sensor_size=(16, 16), window_ms="85")


@pytest.mark.parametrize("name", ["rate", "spiking", "natural"])
def test_an_event_model_given_an_image_says_how_to_make_its_event_frame(name):
    """get_model("rate").run_still(Still(image=img)) said 'run_edfg: pos is None'."""
    from snn_fg.errors import InputError
    from snn_fg.frames.still import Still
    from snn_fg.models import get_model

    with pytest.raises(InputError, match="runs on an event frame, and this Still holds an image only: pos, neg = "):
        get_model(name).run_still(Still(image=np.full((16, 16), 0.5)))


def test_the_frame_model_given_an_event_frame_asks_for_an_image():
    from snn_fg.errors import InputError
    from snn_fg.frames.still import Still
    from snn_fg.models import get_model

    frame = np.zeros((16, 16), np.uint8)
    with pytest.raises(InputError, match="the fbfg model runs on an image, and this Still holds an event frame only"):
        get_model("fbfg").run_still(Still(frame, frame))


def test_get_model_refuses_a_backend_it_has_not_when_made_and_names_every_option():
    """get_model("spiking", backend="gpu") was made, and refused only when it first ran; the rate model's
    unknown-option line left out network and the parameters it takes as keywords."""
    from snn_fg.errors import ParameterError
    from snn_fg.models import get_model

    with pytest.raises(ParameterError, match="backend='gpu' must be one of 'brian2', 'fast'"):
        get_model("spiking", backend="gpu")
    with pytest.raises(ParameterError, match="takes no option bogus \\(it takes params, .*network, and the model "):
        get_model("rate", bogus=1)


@pytest.mark.parametrize("bad", [{"rate_hz": -1.0}, {"rate_hz": True}, {"input_process": "burst"}])
def test_a_frames_trains_are_checked_where_the_options_are_made(bad):
    """FrameOptions left rate_hz and input_process to frame_spikes, which named itself, not run_spiking."""
    pos, neg = image_to_frame(disc(radius=6).image)
    with pytest.raises(ParameterError, match=f"run_spiking: {next(iter(bad))}="):
        run_spiking(pos, neg, **bad)
