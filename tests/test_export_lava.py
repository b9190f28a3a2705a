"""The Lava export: Loihi 2's fixed-point arithmetic step by step, the
lowering into its registers, the export folder, and the loop recording
window -> input.npz -> run.py (numpy reference here; Lava itself in its own
Python 3.10 environment, made once and cached) -> decode -> maps."""

import json

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.export.board import board_network
from snn_fg.lava import fixed
from snn_fg.lowering.loihi2 import current_bound, lower
from snn_fg.network.recipes import RECIPES


def test_one_input_follows_lavas_integer_steps_by_hand():
    """a_in = 10 into du 741, dv 390: u = 10 << 6 = 640, v = 640; next step
    u = trunc(640 * 3354 / 4096) = 524, v = trunc(640 * 3706 / 4096) + 524 =
    579 + 524 = 1103 > 17 << 6 = 1088: a spike, v back to 0. Negative values
    round toward zero (-524, not -525)."""
    regs = {"du": 741, "dv": 390, "bias": 0, "vth": 17}
    u, v, s = fixed.lif_fixed(np.zeros(2, np.int64), np.zeros(2, np.int64), np.array([10, -10]), **regs)
    assert u.tolist() == [640, -640] and v.tolist() == [640, -640] and not s.any()
    u, v, s = fixed.lif_fixed(u, v, np.zeros(2, np.int64), **regs)
    assert u.tolist() == [524, -524] and s.tolist() == [True, False] and v.tolist() == [0, -579 - 524]
    # a refractory cell keeps its voltage; its current goes on decaying
    u2, v2, s2 = fixed.lif_fixed(u, np.array([0, -1103]), np.zeros(2, np.int64), frozen=np.array([True, False]), **regs)
    assert v2[0] == 0 and u2[0] == 524 * 3354 // 4096 and not s2.any()
    # bias: mantissa << exponent, added every step
    assert fixed.effective_bias(-3903, 5) == -3903 * 32
    # the current wraps around at 24 bits (2**23 + 5 -> 5 - 2**23), the voltage saturates
    assert fixed.wrap_current(np.array([2**23 + 5, -(2**23) - 3, 2**23])).tolist() == [5 - 2**23, 2**23 - 3, 2**23]
    _, v, _ = fixed.lif_fixed(
        np.array([-(2**22)]), np.array([10 - 2**23]), np.array([0]), du=0, dv=0, bias=0, vth=2**17 - 1
    )
    assert v.tolist() == [1 - 2**23]
    # a weight exponent below 0 floors the accumulated sum; W = 2 m keeps e = -1 exact
    assert fixed.shift(np.array([-3, 3, -4]), -1).tolist() == [-2, 1, -2]
    pre, post, w = np.array([0, 1, 1]), np.array([0, 0, 1]), np.array([2 * 5, 2 * -3, 2 * 7])
    assert fixed.accumulate(pre, post, w, np.array([True, True]), 2, -1).tolist() == [2, 7]


def test_the_float_model_takes_the_same_numbers():
    f = fixed.float_constants(741, 390, -3903, 5, 6832)
    assert f == {"du": 742 / 4096, "dv": 390 / 4096, "bias": -3903.0 * 32, "vth": 6832.0 * 64}
    assert fixed.float_weights(np.array([2 * 3]), 2).tolist() == [6.0 * 4 * 64]


@pytest.fixture(scope="module")
def compact_64x48():
    net = board_network(RECIPES["compact"].build((48, 64)))
    return net, lower(net)


def test_registers_fit_loihi2_and_hold_threshold_rest_and_decays(compact_64x48):
    net, low = compact_64x48
    for p in net.populations:
        if p.neuron is None:
            continue
        r, n = low.neurons[p.name], p.neuron
        assert 0 <= r.du <= 4095 and 0 <= r.dv <= 4095 and 0 < r.vth <= 2**17 - 1, p.name
        assert abs(r.bias_mant) <= 4095 and 0 <= r.bias_exp <= 7, p.name
        assert r.vth * 64 / r.unit_per_mv == pytest.approx(n.v_th_mv - n.v_reset_mv, rel=1e-12), p.name
        rest = fixed.effective_bias(r.bias_mant, r.bias_exp) / (r.dv / 4096) / r.unit_per_mv if r.dv else 0.0
        assert rest == pytest.approx(n.v_rest_mv - n.v_reset_mv, abs=0.01), p.name
        f = n.propagators(net.dt_ms)
        assert (
            abs((4096 - r.du - 1) / 4096 - f["d_exc"]) <= 0.5 / 4096
            and abs((4096 - r.dv) / 4096 - f["d_m"]) <= 0.5 / 4096
        )
        # every source at its fastest through every synapse of one sign: the current stays inside 24 bits
        syn = {pr.name: low.synapses[pr.name] for pr in net.projections if pr.target == p.name}
        assert current_bound(net, p.name, r.du, syn) <= 2**23 - 1, p.name


def test_mantissas_are_8_bits_and_use_them(compact_64x48):
    """Each projection's largest |drive| lands on a mantissa of 64..127 (less only where its
    exponent is already -1), and a mantissa moves v as the description's weight does."""
    from snn_fg.lowering.quantise import peak_weight

    net, low = compact_64x48
    for pr in net.projections:
        s = low.synapses[pr.name]
        top = int(fixed.mantissas(peak_weight(net, pr), s.factor))
        assert top <= 127 and (top >= 64 or s.weight_exp == -1), (pr.name, top, s.weight_exp)
        r = low.neurons[pr.target]
        p = net.population(pr.target).neuron.propagators(net.dt_ms)["p_exc"]
        # one mantissa step is 2 << e << 6 current units = 2**(7 + e) / unit mV of voltage step, i.e. / p mV of drive
        assert 2.0 ** (7 + s.weight_exp) / r.unit_per_mv / p == pytest.approx(1 / s.factor, rel=1e-12)


def test_a_neuron_with_two_synaptic_time_constants_is_refused_in_one_line(tmp_path, capsys):
    import dataclasses

    from snn_fg.export.lava import export_lava
    from snn_fg.network import build_network
    from snn_fg.params import ModelParams

    net = build_network(ModelParams(levels=1, r0=4), (24, 24))
    pops = tuple(
        dataclasses.replace(p, neuron=dataclasses.replace(p.neuron, tau_inh_ms=10.0)) if p.role == "untuned" else p
        for p in net.populations
    )
    from snn_fg.errors import InputError

    with pytest.raises(InputError, match="population 'untuned_1'.*one synaptic current"):
        export_lava(dataclasses.replace(net, populations=pops), tmp_path / "m")
    assert not (tmp_path / "m").exists()


def test_export_command_writes_the_folder_and_refuses_weight_bits(tmp_path, capsys):
    out = tmp_path / "model"
    argv = ["export", "--format", "lava", "--network", "compact", "--sensor-size", "64x48", "--out", str(out)]
    assert main(argv) == 0
    assert "its run.py needs Python 3.10" in capsys.readouterr().out
    readme = (out / "README.md").read_text()
    assert "python3.10 -m venv .venv-lava" in readme and ".venv-lava/bin/pip install -r requirements.txt" in readme
    assert "lava-nc==0.10.0" in (out / "requirements.txt").read_text()
    meta = json.loads((out / "network.json").read_text())
    assert meta["schema"] == "snn-fg.lava/1" and meta["weight_bits"] == 8
    assert all(p["lava"]["vth"] > 0 for p in meta["populations"] if p["neuron"])
    assert meta["export_command"].startswith("snn-fg export --format lava")
    assert main([*argv, "--force", "--weight-bits", "6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--weight-bits" in err[0]


def _small_export(tmp_path, disc_recording, capsys):
    """A one-level export of a 16 x 16 sensor and its input from the disc's recording (with the window clock)."""
    out = tmp_path / "model"
    assert (
        main(["export", "--format", "lava", "--levels", "1", "--r0", "4", "--sensor-size", "16x16", "--out", str(out)])
        == 0
    )
    assert (
        main(
            [
                "events",
                str(disc_recording),
                "--write-spikes",
                str(out / "input.npz"),
                "--export",
                str(out),
                "--window-ms",
                "40",
                "--no-progress",
            ]
        )
        == 0
    )
    capsys.readouterr()
    return out


def test_loop_with_the_numpy_reference_gives_maps_near_the_fast_engines(tmp_path, disc_recording, capsys, run_py):
    """run.py --simulator reference needs numpy alone (it runs here, on 3.11,
    without snn_fg); its counts decode to maps that agree with the fast
    engine's 8-bit run on the same input file, in the file it names; and run.py asked for Lava on
    this Python stops with one line saying what to make."""
    from snn_fg.backends import RunSettings, get_backend
    from snn_fg.export.loop import export_network
    from snn_fg.export.pynn import read_input
    from snn_fg.models.spiking.decode import decode
    from snn_fg.results.maps import Maps
    from snn_fg.scoring.metrics import agreement

    out = _small_export(tmp_path, disc_recording, capsys)
    done = run_py(
        out,
        "--input",
        "input.npz",
        "--out",
        "counts",
        "--duration-ms",
        "80",
        "--simulator",
        "reference",
    )
    assert done.returncode == 0, done.stderr[-2000:]
    # (the name numpy gives the file, said as written; no temporary part left beside it)
    assert done.stdout.strip().endswith("wrote counts.npz"), done.stdout
    assert not list(out.glob(".*part*"))
    assert main(["decode", str(out / "counts.npz"), "--export", str(out), "--out", str(tmp_path / "maps")]) == 0
    ours = Maps.load(tmp_path / "maps" / "maps.npz")
    assert ours.params["backend"]["name"] == "lava-export"  # (until 30 Nov: "pynn-export", as every export's)
    net, _ = export_network(out)
    fast = get_backend("fast", weight_bits=8).simulate(
        net,
        read_input(out / "input.npz"),
        RunSettings(duration_ms=80.0, dt_ms=net.dt_ms, count_from_ms=40.0, instantiate="all"),
    )
    a = agreement(ours, decode(fast)[:3])
    assert np.abs(ours.grouping).max() > 0 and a["grouping_r"] >= 0.9 and a["within_45"] >= 0.85, a
    done = run_py(out, "--input", "input.npz", "--out", "c2.npz")
    err = done.stderr.strip().splitlines()
    assert done.returncode == 1 and len(err) == 1 and "lava-nc 0.10 needs Python 3.8-3.10" in err[0]
    assert "pip install -r requirements.txt" in err[0] and not (out / "c2.npz").exists()


@pytest.mark.slow
def test_lava_fixed_point_runs_the_export_spike_for_spike_as_the_reference(tmp_path, disc_recording, capsys, run_py):
    """The loop closed in Lava: run.py in its own Python 3.10 environment
    (made once, cached by the requirements' hash) runs Lava's fixed_pt and
    gives the numpy reference's count in every cell; decode gives the same
    maps; --count-only counts what the report counts."""
    from snn_fg.export.lava_env import LavaEnvMissing, lava_python
    from snn_fg.results.maps import Maps

    try:
        python = lava_python()
    except LavaEnvMissing as e:
        pytest.skip(f"no Lava environment: {e}")
    out = _small_export(tmp_path, disc_recording, capsys)
    for simulator, name in (("lava", "lava.npz"), ("reference", "ref.npz")):
        args = ("--input", "input.npz", "--out", name, "--duration-ms", "60", "--simulator", simulator)
        done = run_py(out, *args, python=python)
        assert done.returncode == 0, done.stderr[-2000:]
    lava, ref = np.load(out / "lava.npz"), np.load(out / "ref.npz")
    names = [k for k in ref.files if k.startswith("count_") and k != "count_from_ms"]
    assert names and sum(int(ref[k].sum()) for k in names) > 0
    assert all(np.array_equal(lava[k], ref[k]) for k in names)
    for name in ("lava", "ref"):
        assert main(["decode", str(out / f"{name}.npz"), "--export", str(out), "--out", str(tmp_path / name)]) == 0
    a, b = (Maps.load(tmp_path / n / "maps.npz") for n in ("lava", "ref"))
    assert np.array_equal(a.fg_x, b.fg_x) and np.array_equal(a.grouping, b.grouping)
    done = run_py(out, "--count-only", python=python)
    assert done.returncode == 0, done.stderr[-2000:]
    res = json.loads((out / "resources.json").read_text())
    assert res["lava"]["neurons"] == res["snn_fg_report"]["neurons"]
    assert 0 < res["lava"]["synapses"] <= res["snn_fg_report"]["synapses"]
