"""Hand-built circuits from the description, simulated in Brian2, with
hand-computable outcomes: the footprint of one input spike, and a ring of
border-ownership cells driving the grouping cell at its centre."""
import numpy as np
import pytest
from scipy import ndimage

from snn_fg.network.description import Conv, Kernel, Network, Neuron, Population
from snn_fg.network.kernels import dog_kernels, von_mises_masks
from snn_fg.params import ModelParams
from snn_fg.spiking.brian import simulate
from snn_fg.spiking.inputs import InputSpikes, frame_spikes
from snn_fg.spiking.unroll import unroll

P1 = ModelParams(levels=1)


def _sources(shape):
    return (Population("on", "input_on", 1, shape), Population("off", "input_off", 1, shape))


@pytest.mark.parametrize("direction, prune", [(2, 0.05), (11, 0.2)])
def test_one_input_spike_reaches_exactly_the_dog_footprint(direction, prune):
    shape = (41, 41)
    c = (20, 20)
    pops = _sources(shape) + (Population("T", "simple", 1, shape, 1, 1, Neuron(), "all"),)
    src = "on" if direction < 8 else "off"
    prj = (Conv("in_to_T", src, "T", Kernel("dog", {"directions": [direction]}), "conv", "wrap", 1, 500.0, 1.0,
                prune),)
    net = Network(P1, shape, pops, prj)
    mask = np.zeros(shape, bool)
    mask[c] = True
    zero = np.zeros(shape, bool)
    act = {"on": mask, "off": zero} if src == "on" else {"on": zero, "off": mask}
    un = unroll(net, act)
    idx = c[0] * shape[1] + c[1] + (0 if src == "on" else shape[0] * shape[1])
    inp = InputSpikes(shape, np.array([idx]), np.array([2]), None, act["on"], act["off"], 200.0)
    res = simulate(un, inp, duration_ms=4.0, dt_ms=0.5, count_from_ms=0.0, record_spikes=False, progress=False,
                   final_state=("I_exc",))
    current = res.final_state["I_exc"].reshape(shape)
    # expected: the kernel laid around the input pixel (a convolution puts
    # K[d] at target = source + d), taps below prune*max|K| left out
    k = dog_kernels(P1)[direction]
    k = np.where(np.abs(k) >= prune * np.abs(k).max(), k, 0.0)
    want = np.zeros(shape)
    h = k.shape[0] // 2
    want[c[0] - h:c[0] + h + 1, c[1] - h:c[1] + h + 1] = k
    assert np.array_equal(current != 0, want != 0)
    assert np.array_equal(np.sign(current), np.sign(want))
    ratio = current[want != 0] / want[want != 0]
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
    assert ratio[0] > 0


def test_a_ring_of_border_ownership_cells_drives_the_grouping_cell_at_its_centre():
    shape = (64, 64)
    c = (32, 32)
    params = ModelParams(levels=1)
    m2 = von_mises_masks(params)[1]
    h = m2.shape[-1] // 2
    r0 = params.r0
    y, x = np.mgrid[:shape[0], :shape[1]]
    dist = np.hypot(y - c[0], x - c[1])
    ring = (dist >= r0 - 0.5) & (dist < r0 + 0.5)
    # each ring pixel: the orientation whose half ring (m2) reaches the centre most
    b_cells = []
    pattern = np.zeros((8,) + shape)
    for i, j in zip(*np.nonzero(ring)):
        o = int(np.argmax(m2[:, i - c[0] + h, j - c[1] + h]))   # G(c) sees B(c + d) through m2(d)
        b_cells.append((o * shape[0] + i) * shape[1] + j)
        pattern[o, i, j] = 1
    drive = sum(ndimage.correlate(pattern[o], m2[o], mode="constant") for o in range(8))
    b_neuron = Neuron(tau_m_ms=10, t_ref_ms=5)
    g_neuron = Neuron(tau_m_ms=20, t_ref_ms=1)
    # B: 4 thresholds of input current at 200 Hz; G: 3 thresholds at the centre
    # if the B cells fire at 100 Hz
    g_in = 4 * 10.0 / (200 * 0.005)
    g_bg = 3 * 10.0 / (100 * 0.005 * drive[c])
    pops = _sources(shape) + (Population("B", "bo_L1", 1, shape, 8, 1, b_neuron, "all"),
                              Population("G", "group_L", 1, shape, 1, 2, g_neuron, "all"))
    prj = (Conv("on_to_B", "on", "B", Kernel("channel_map", {"n_out": 8, "n_in": 1,
                                                            "entries": [[o, 0, 1.0] for o in range(8)]}),
                "corr", "zero", 1, g_in, 1.0),
           Conv("B_to_G", "B", "G", Kernel("von_mises", {"half": 2, "layout": "gather"}), "corr", "zero", 1, g_bg, 1.0))
    net = Network(params, shape, pops, prj)
    un = unroll(net, {"on": ring, "off": np.zeros(shape, bool)}, sites={"B": b_cells})
    assert un.n_cells("B") == ring.sum()
    inp = frame_spikes(ring.astype(np.uint8), np.zeros(shape, np.uint8), 200.0, 0.5, 200.0, seed=3)
    res = simulate(un, inp, duration_ms=200.0, dt_ms=0.5, count_from_ms=50.0, record_spikes=False,
                   progress=False)
    lay = res.layout
    b_rate = res.counts[lay.offsets["B"]:lay.offsets["B"] + lay.sizes["B"]] / 0.15
    assert np.all(b_rate > 50)                       # the ring is active
    g = np.zeros(net.population("G").size)
    g[un.sites["G"]] = res.counts[lay.offsets["G"]:lay.offsets["G"] + lay.sizes["G"]]
    g = g.reshape(net.population("G").grid)
    d_lat = dist[::2, ::2]
    centre = (c[0] // 2, c[1] // 2)
    assert g[centre] > 0 and g[centre] == g.max()
    # outside the ring the expected drive is < 0.16 of the centre's: silent
    assert drive[::2, ::2][d_lat >= r0 + 2].max() < 0.16 * drive[c]
    assert g[d_lat >= r0 + 2].max() == 0
    # and the grouping activity falls off from the centre like the drive does
    inside = d_lat <= 4
    assert np.corrcoef(g[inside], drive[::2, ::2][inside])[0, 1] > 0.8
