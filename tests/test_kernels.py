"""Unit tests of the model's parts: von Mises masks, DoG orientation, pyramid."""

import numpy as np
import pytest

from snn_fg.errors import ParameterError
from snn_fg.frames.pyramid import level_shape, pyramid
from snn_fg.models.rate.edfg import orientation_index, oriented_responses
from snn_fg.network.kernels import dog_kernels, von_mises_masks
from snn_fg.params import ModelParams


@pytest.mark.parametrize("r0", [4, 8, 12])
def test_von_mises_ring_peaks_at_r0(r0):
    m1, m2 = von_mises_masks(ModelParams(r0=r0))
    half = m1.shape[-1] // 2
    y, x = np.mgrid[half : -half - 1 : -1, -half : half + 1]
    r = np.hypot(x, y)
    for o in range(8):
        for m in (m1[o], m2[o]):
            radial = [m[(r >= k - 0.5) & (r < k + 0.5)].max() for k in range(1, half)]
            assert abs(1 + int(np.argmax(radial)) - r0) <= 1


def test_von_mises_masks_are_disjoint_and_on_preferred_side():
    m1, m2 = von_mises_masks()
    half = m1.shape[-1] // 2
    y, x = np.mgrid[half : -half - 1 : -1, -half : half + 1]
    assert m1[:, half, half].max() == 0 and m2[:, half, half].max() == 0
    for o in range(8):
        assert not np.any((m1[o] > 0) & (m2[o] > 0))
        theta0 = np.pi * o / 8 + np.pi / 2
        # weighted mean direction of m1 points along theta0, m2 opposite
        for m, want in ((m1[o], theta0), (m2[o], theta0 + np.pi)):
            ang = np.arctan2((m * y).sum(), (m * x).sum())
            assert abs(np.angle(np.exp(1j * (ang - want)))) < np.radians(1)


def _line(shape, angle_deg, half_len=12):
    """Pixels of a straight line through the centre at ``angle_deg`` (x right, y up)."""
    img = np.zeros(shape, np.uint8)
    c = np.array(shape) // 2
    a = np.radians(angle_deg)
    for t in np.linspace(-half_len, half_len, 8 * half_len):
        img[int(round(c[0] - t * np.sin(a))), int(round(c[1] + t * np.cos(a)))] = 1
    return img


@pytest.mark.parametrize("k", range(16))
def test_dog_orientation_of_straight_edge(k):
    # Direction k's kernel is the base kernel (band along the rows, i.e. a
    # vertical line) turned 22.5*k degrees counter-clockwise; directions 0-7
    # see ON events, 8-15 OFF events.
    line = _line((41, 41), 90 + 22.5 * (k % 8))
    zero = np.zeros_like(line)
    pos, neg = (line, zero) if k < 8 else (zero, line)
    resp = oriented_responses(pos.astype(float), neg.astype(float))
    winner, index = orientation_index(resp)
    centre = winner[15:26, 15:26][line[15:26, 15:26] > 0]
    assert np.mean(centre == k) > 0.8
    assert np.all(index[winner == k] == (k + 4) % 16)


def test_dog_kernel_shape_and_symmetry():
    k = dog_kernels()
    assert k.shape == (16, 31, 31)
    # Rotating by 180 degrees leaves the DoG unchanged (polarity separates them).
    assert np.allclose(k[0], k[8], atol=1e-12)
    assert k[0][:, 15].sum() > 0 > k[0][15, :3].sum()


def test_pyramid_sizes():
    assert level_shape((321, 481), 1) == (321, 481)
    assert level_shape((321, 481), 2) == (227, 341)
    assert level_shape((321, 481), 3) == (161, 241)
    assert level_shape((321, 481), 10) == (15, 22)
    levels = pyramid(np.ones((240, 304)), 10)
    assert [a.shape for a in levels][-1] == (11, 14)
    assert np.allclose(levels[3], 1.0)


def test_params_round_trip_and_validation():
    p = ModelParams(r0=10, levels=6)
    assert ModelParams.from_dict(p.to_dict()) == p
    with pytest.raises(ParameterError, match="r0"):
        ModelParams(r0=-1)
    with pytest.raises(ParameterError, match="levels"):
        ModelParams(levels=0)
    with pytest.raises(ParameterError, match="unknown"):
        ModelParams.from_dict({"radius": 3})


@pytest.mark.parametrize(
    "name, bad, flag", [("n_ori", 1, "--n-ori"), ("iterations", 0, "--iterations"), ("w_inh", -1.0, "--w-inh")]
)
def test_the_python_api_and_the_command_line_refuse_the_same_values(name, bad, flag):
    """ModelParams took n_ori=1, iterations=0 (a map without a vector) and w_inh=-1 that snn-fg run
    refused: the two front doors had their own bounds (a maintainer's read, 1 Dec)."""
    import argparse

    from snn_fg.cli.run_options import add_option_groups

    with pytest.raises(ParameterError, match=name):
        ModelParams(**{name: bad})
    parser = argparse.ArgumentParser(exit_on_error=False)
    add_option_groups(parser)
    with pytest.raises(argparse.ArgumentError, match="must be >="):
        parser.parse_args([flag, str(bad)])
    ModelParams(**{name: type(bad)(2)})  # (just inside: both take it)
    assert parser.parse_args([flag, "2"])
