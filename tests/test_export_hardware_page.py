"""export_hardware's page says what it measured: a target that no configuration tried fits is named (with
the configuration nearest to fitting), not left out of the table in silence, and each part names the run
that measured it."""

from __future__ import annotations

from experiments.validation.export_hardware import _markdown

RUN = {
    "commit": "abc",
    "command": "python -m experiments.validation.export_hardware fit",
    "date": "2026-11-30 18:42 UTC",
    "seconds": 480.0,
    "load_before": [2.0],
    "load_after": [3.3],
}


def _row(w, h, spinnaker_chips, loihi2_chips):
    return {
        "sensor": [w, h],
        "levels": 4,
        "n_ori": 4,
        "neurons": w * h * 100,
        "synapses": w * h * 1000,
        "spinnaker_chips": spinnaker_chips,
        "loihi2_chips": loihi2_chips,
        "loihi2_cores": 100,
        "spinn5": spinnaker_chips <= 48,
        "loihi2": loihi2_chips <= 1,
    }


def _fit():
    tried = [_row(40, 30, 53, 1), _row(48, 36, 60, 2)]
    return {"tried": tried, "largest": {"loihi2": tried[0]}, "fidelity": {}}


def test_a_target_no_configuration_fits_is_said_with_the_nearest():
    page = "\n".join(_markdown({"fit": _fit(), "runs": {"fit": RUN}}))
    assert "| loihi2 | 40x30 |" in page
    assert "| spinn5 |" not in page
    assert (
        "spinn5: none of the 2 configurations tried fits (48 chips at most); the fewest chips, 53, are 40x30's "
        "with 4 levels and 4 orientations." in page
    )
    assert "loihi2: none" not in page


def test_each_part_names_its_run():
    page = _markdown({"fit": _fit(), "quantisation": [], "runs": {"fit": RUN}})
    said = f"- `fit`: `{RUN['command']}` at abc, 2026-11-30 18:42 UTC: 8.0 min, load average 2.0 before, 3.3 after."
    assert said in page
    assert "- `quant`: run before each part kept its own record." in page
    assert not any(line.startswith("- `reports`") for line in page)
