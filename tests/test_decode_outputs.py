"""``snn-fg decode --reference`` as a new user met it: an uncalibrated export whose board run and
reference both made no figure-ground vector printed "nan %" as a result, and decoding again into the
same folder with ``--force`` was refused because of the ``reference/`` decode itself had written."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from snn_fg.backends.base import lif_populations
from snn_fg.cli import main
from snn_fg.cli.decode import agreement_line
from snn_fg.export.board import board_network
from snn_fg.export.loop import export_network
from snn_fg.export.pynn import export_pynn
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps


@pytest.fixture(scope="module")
def board_run(tmp_path_factory):
    """A small export, its input (a square's outline, each pixel one spike every 70 ms: about 17 Hz,
    far below the 200 Hz its gains are set for) and a board run's counts that hold no spike."""
    tmp = tmp_path_factory.mktemp("board")
    folder = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 24)), tmp / "model")
    net, _ = export_network(folder)
    idx, steps = [], []
    for r in range(6, 18):
        for c in range(6, 18):
            if r in (6, 17) or c in (6, 17):
                idx += [r * 24 + c] * 6
                steps += [t + (r + c) % 7 for t in range(0, 840, 140)]
    inp = dict(indices=np.array(idx), steps=np.array(steps), dt_ms=net.dt_ms, period_steps=-1, shape=np.array([24, 24]))
    np.savez(folder / "input.npz", **inp)
    silent = {f"count_{q.name}": np.zeros(q.size, np.int64) for q in lif_populations(board_network(net))}
    np.savez(folder / "counts.npz", duration_ms=400.0, count_from_ms=200.0, dt_ms=net.dt_ms, **silent)
    return folder


def _decode(folder, out, *extra):
    return main(["decode", str(folder / "counts.npz"), "--export", str(folder), "--out", str(out), *extra])


@pytest.mark.slow
def test_no_vector_in_either_map_is_said_with_its_cause_never_as_nan(board_run, tmp_path, capsys):
    assert _decode(board_run, tmp_path / "maps", "--reference", "fast") == 0
    said = capsys.readouterr().out.strip().splitlines()[-1]
    assert "nan" not in said, said
    assert "neither the board's maps nor the reference have a figure-ground vector, nothing to compare" in said
    assert "times the 200 Hz the export's gains are set for" in said and "--input-rate-hz 17" in said
    for m in (Maps.load(tmp_path / "maps"), Maps.load(tmp_path / "maps" / "reference")):
        assert not np.hypot(m.fg_x, m.fg_y).any()  # (what the line says)


def test_a_map_with_vectors_against_one_without_is_said_without_nan(tmp_path):
    net, _ = export_network(export_pynn(build_network(ModelParams(levels=1, r0=4), (12, 12)), tmp_path / "m"))
    z = np.zeros((12, 12), np.float32)
    some = z.copy()
    some[3, 2:9] = 1.0
    full, empty = Maps(some, z, some, {}), Maps(z, z, z, {})
    for a, b, who in ((full, empty, "the board's maps"), (empty, full, "the reference")):
        line = agreement_line(a, b, "fast", 200.0, net, None)
        assert "nan" not in line and f"only {who} have a figure-ground vector (7 pixels)" in line, line
        assert "--input-rate-hz" not in line  # (a calibrated input: not the cause)
    line = agreement_line(full, full, "fast", 35.0, net, "snn-fg export --format pynn --out m")
    assert "grouping r 1.000, within 45 degrees on 100.0 % of the 7 pixels where both have a vector," in line


@pytest.mark.slow
def test_decode_again_into_its_own_folder_with_reference_and_force(board_run, tmp_path, capsys):
    """The folder an earlier ``decode --reference`` wrote holds reference/, which decode wrote: --force
    replaces it; a user's file beside it, or in a reference/ of their own, is still refused, nothing deleted."""
    out = tmp_path / "maps2"
    assert _decode(board_run, out, "--reference", "fast") == 0
    assert _decode(board_run, out, "--reference", "fast", "--force") == 0
    assert sorted(p.name for p in out.iterdir()) == ["maps.npz", "maps.png", "reference"]
    assert _decode(board_run, out, "--force") == 0  # (and without --reference: reference/ goes)
    assert sorted(p.name for p in out.iterdir()) == ["maps.npz", "maps.png"]
    assert _decode(board_run, out, "--reference", "fast", "--force") == 0
    capsys.readouterr()
    for extra in (out / "notes.txt", out / "reference" / "notes.txt"):
        extra.write_text("mine")
        before = sorted(str(p.relative_to(out)) for p in out.rglob("*"))
        assert _decode(board_run, out, "--reference", "fast", "--force") == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "which snn-fg did not write" in err[0] and "nothing was deleted" in err[0], err
        assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == before and extra.read_text() == "mine"
        extra.unlink()


def _edited(folder, tmp_path, edit):
    """A copy of the export ``folder`` whose network.json's top level ``edit(meta)`` changed, as a user edits it."""
    copy = tmp_path / "edited"
    shutil.copytree(folder, copy)
    meta = json.loads((copy / "network.json").read_text())
    edit(meta)
    (copy / "network.json").write_text(json.dumps(meta, indent=1))
    return copy


@pytest.mark.slow
def test_an_edited_export_is_no_longer_called_the_same_network(board_run, tmp_path, capsys):
    """run.py builds network.json's populations and projections, the reference the description embedded
    beside them: with a gain edited (a new user set the feedback cells' inhibition of the border-ownership
    cells from 400 to 100), --reference is refused in one line naming the field, old -> new; a plain decode
    goes on (the counts are placed by the populations, which the edit leaves) and says so; an edited
    population size is refused either way. An unedited export decodes without a word of it (and is
    still called the same network by --reference: the tests above)."""

    def gains(meta):
        for p in meta["projections"]:
            if "_inh_bo_" in p["name"]:
                p["gain_mv"] = 100.0

    edited = _edited(board_run, tmp_path, gains)
    exported = json.loads((board_run / "network.json").read_text())["projections"]
    first = next(p for p in exported if "_inh_bo_" in p["name"])
    assert _decode(edited, tmp_path / "ref", "--reference", "fast") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "network.json: differs from the snn-fg description it embeds" in err[0], err
    assert f"projection {first['name']} gain_mv {json.dumps(first['gain_mv'])} -> 100.0" in err[0], err
    assert "export it again with --network" in err[0] and not (tmp_path / "ref").exists()
    assert _decode(edited, tmp_path / "plain") == 0
    said = capsys.readouterr().out
    assert "snn-fg: note:" in said and f"{first['name']} gain_mv" in said and (tmp_path / "plain" / "maps.npz").exists()
    # the input spikes for it: written for the embedded description, and said so
    frame = tmp_path / "frame.npz"
    pos = np.zeros((24, 24), np.uint8)
    pos[6:18, 6] = 1
    np.savez(frame, pos=pos, neg=np.zeros_like(pos))
    spikes = ["events", str(frame), "--write-spikes", str(tmp_path / "in.npz"), "--export"]
    assert main([*spikes, str(edited)]) == 0
    said = capsys.readouterr().out
    assert "snn-fg: note:" in said and "the spikes are written for the embedded description's populations" in said

    def size(meta):
        meta["populations"][-1]["size"] += 1

    resized = _edited(board_run, tmp_path / "s", size)
    assert _decode(resized, tmp_path / "plain2") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "its populations differ" in err[0] and " size " in err[0], err
    assert main([*spikes[:3], str(tmp_path / "in2.npz"), "--export", str(resized)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "its populations differ" in err[0] and not (tmp_path / "in2.npz").exists(), err
    assert _decode(board_run, tmp_path / "same") == 0  # (and with --reference: the tests above)
    assert "note" not in capsys.readouterr().out
