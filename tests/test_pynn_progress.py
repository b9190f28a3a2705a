"""A PyNN export's run.py says how far its run is, each line further than the last: the steps
simulated past the duration (the input shift and the last count edge's step) said "simulated
400/400 ms" a second time."""

from snn_fg.pynn.readout import TIME_SHIFT_STEPS, Readout


class _Sim:
    def __init__(self):
        self.ran = []

    def run(self, ms):
        self.ran.append(ms)


def test_each_progress_report_moves_on_and_the_duration_is_said_once():
    net = Readout()
    net.sim, net.dt = _Sim(), 0.5
    net.shift_ms = TIME_SHIFT_STEPS * net.dt
    said = []
    net.run(400.0, chunk_ms=50.0, report=said.append)
    assert sum(net.sim.ran) == 400.0 + net.shift_ms + net.dt  # (all of it simulated)
    assert said == [50.0 * k for k in range(1, 9)]
