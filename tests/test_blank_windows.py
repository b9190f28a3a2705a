"""The warning for a recording's windows that have events and no figure-ground vector gives the
reason that fits them: too short for the network to settle, or too few events to drive it."""

from snn_fg.models.blank import SPIKING


def test_short_windows_are_told_to_run_as_their_frame():
    said = SPIKING.why([30.0, 44.0], [900, 1200])
    assert "A clip that short" in said and "--write-frame" in said


def test_full_length_windows_with_few_events_are_not_called_short():
    # (a new user's trial: an 85 ms window in the middle of a 0.5 s recording was called "a clip that short")
    said = SPIKING.why([85.0], [412])
    assert "short" not in said and "412 events a window, and long enough" in said and "--model rate" in said
    assert "1,000-2,500 events" in SPIKING.why([84.0, 85.0], [2500, 1000])
