"""SpiNN-5 boards: how many a network needs, and how wide a sensor one holds.

A SpiNN-5 board has 48 chips of 18 cores (SpiNNMachine). sPyNNaker keeps two
cores of every chip (SCAMP's monitor and its own extra monitor) and one more
on the board's Ethernet chip (the packet gatherer), so a board gives the
network 48 x 16 - 1 = 767 cores (:func:`board_cores`; those 49 system cores
a board are in every mapping of ``experiments/results/export_spinnaker.json``).

* Boards (:func:`boards_needed`): the network's cores over 767, or the chips
  its synaptic memory needs over 48, whichever is more. More than one board
  is allocated as a rectangle of triads of 3 boards, as spalloc does and as
  sPyNNaker sizes its virtual machine (:func:`boards_allocated`: 4 boards'
  worth is a machine of 6).
* Chips (:func:`chips_estimate`): the cores at 15 a chip, as sPyNNaker's
  placement filled chips of 16 free cores with our exports (14.0-15.8), but
  no more than the boards' 48 chips each, as placement packs tighter when a
  board is full (756 network cores on one board's 48 chips).

Fit on one board is not monotonic in the sensor's size: sPyNNaker cuts a 2-D
population into tiles whose sides divide its grid's, so a grid side with few
divisors costs more cores than a larger one (the compact network needs 807
cores at 148 x 117, 756 at 150 x 118). :func:`cores_by_width` therefore counts
every width, up to the widest whose cells alone could fit one board.
"""

from __future__ import annotations

import math

from ..errors import SnnFgError
from ..pynn.cells import delay_steps
from ..pynn.spinnaker import CELLS_PER_CORE
from .board import board_network
from .hardware import SPINNAKER1
from .spinnaker import spinnaker_cores

#: the widest sensor searched (a network that does not grow with its sensor fits at every width)
MOST_WIDTH = 1 << 16
#: how the report counts chips and boards (printed under its SpiNNaker 1 line)
COUNTED = (
    "counted: a SpiNN-5 board gives the network 767 cores (48 chips x 18, less 2 a chip for sPyNNaker's "
    "monitors and 1 for its packet gatherer); boards = cores / 767, more than one allocated in triads of 3; "
    "chips = cores / 15, as sPyNNaker's placement fills them, at most 48 a board"
)


def board_cores() -> int:
    """The cores one SpiNN-5 board gives the network (767)."""
    lim = SPINNAKER1
    return int(lim["chips_per_board"].value * lim["cores_per_chip"].value - lim["gatherer_cores_per_board"].value)


def network_cores(network, dt_ms: float) -> dict:
    """The network's SpiNNaker 1 cores (``network`` a board network): ``by_population`` as the PyNN
    export builds it on sPyNNaker (:func:`~.spinnaker.spinnaker_cores`), ``delay_extension_sources``
    (the sources of delays over the cores' 32 slots, one delay-extension core per 256 of their
    cells) and ``cores``, the sum of both."""
    lim = SPINNAKER1
    by_population = spinnaker_cores(network, dt_ms)
    slots = lim["delay_slots"].value
    long_src = sorted({pr.source for pr in network.projections if delay_steps(pr.delay_ms, dt_ms) > slots})
    extension = sum(math.ceil(network.population(n).size / lim["neurons_per_core"].value) for n in long_src)
    return {
        "by_population": by_population,
        "delay_extension_sources": long_src,
        "cores": sum(by_population.values()) + extension,
    }


def boards_needed(cores: int, memory_chips: int) -> int:
    """SpiNN-5 boards for ``cores`` network cores and ``memory_chips`` chips of synaptic memory."""
    return max(1, math.ceil(cores / board_cores()), math.ceil(memory_chips / SPINNAKER1["chips_per_board"].value))


def boards_allocated(boards: int) -> int:
    """The boards of the machine that holds ``boards``: one, or a rectangle of triads as near
    square as it goes (SpiNNMachine's ``size_from_n_boards``)."""
    if boards <= 1:
        return 1
    per = int(SPINNAKER1["boards_per_triad"].value)
    triads = math.ceil(boards / per)
    width = math.ceil(math.sqrt(triads))
    return per * width * math.ceil(triads / width)


def chips_estimate(cores: int, memory_chips: int, boards: int) -> int:
    """Chips used: ``cores`` at 15 a chip or the synaptic memory's chips, at most the boards' chips."""
    lim = SPINNAKER1
    placed = math.ceil(cores / lim["cores_placed_per_chip"].value)
    return min(max(placed, memory_chips), boards * int(lim["chips_per_board"].value))


def shape_at(width: int, sensor_shape) -> tuple[int, int]:
    """The sensor (rows, cols) ``width`` wide with the aspect of ``sensor_shape`` (rows, cols)."""
    h, w = sensor_shape
    return (max(1, round(width * h / w)), width)


def _least_cores(network) -> int:
    """Cores the network's cells need at the least (256 a core, spike sources left out): a bound
    that grows with the sensor, as every population does."""
    return sum(math.ceil(p.size / CELLS_PER_CORE) for p in network.populations if not p.is_source)


def _build(make, width: int, sensor_shape):
    try:
        return board_network(make(shape_at(width, sensor_shape)))
    except SnnFgError:  # too small for the network's levels
        return None


def widest_bound(make, sensor_shape) -> int:
    """The widest sensor (of ``sensor_shape``'s aspect) whose cells alone could fit one board:
    wider ones need more than :func:`board_cores` cores at 256 cells a core. Found by doubling,
    then halving, over that bound, which grows with the width; whatever ``sensor_shape`` was."""
    board = board_cores()

    def fits(width):
        net = _build(make, width, sensor_shape)
        return net is None or _least_cores(net) <= board

    hi = 1
    while fits(hi) and hi < MOST_WIDTH:
        hi *= 2
    if fits(hi):
        return hi
    lo = hi // 2  # fits(lo), not fits(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return lo


def cores_by_width(make, sensor_shape, dt_ms: float) -> dict[int, int]:
    """Every width from 1 to :func:`widest_bound` -> the network's cores (:func:`network_cores`)
    for that sensor (``make(shape)`` builds its network); widths too small for the network are
    left out."""
    out = {}
    for width in range(1, widest_bound(make, sensor_shape) + 1):
        net = _build(make, width, sensor_shape)
        if net is not None:
            out[width] = network_cores(net, net.time_step(dt_ms, "cores_by_width"))["cores"]
    return out


def width_ranges(widths) -> str:
    """Widths as runs: ``136-137, 142-144, 148``."""
    runs: list[list[int]] = []
    for w in sorted(widths):
        if runs and w == runs[-1][1] + 1:
            runs[-1][1] = w
        else:
            runs.append([w, w])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs)


def widest_on_one_board(make, sensor_shape, dt_ms, targets) -> dict | None:
    """The widest sensor of ``sensor_shape``'s aspect (rows, cols) whose network (``make(shape)``)
    fits one SpiNN-5 board: at most :func:`board_cores` cores, one board and no violated limit by
    its report (``targets(network)``: the report's targets). Every width up to the widest whose
    cells alone could fit is counted (:func:`cores_by_width`), so the answer is the same whatever
    size was asked. ``{"width", "height", "cores", "chips", "board_cores", "widths_searched",
    "narrower_not_fitting"}`` (the narrower widths whose cores exceed a board's); ``None`` if no
    width fits."""
    cores = cores_by_width(make, sensor_shape, dt_ms)
    board = board_cores()
    for width in sorted((w for w, c in cores.items() if c <= board), reverse=True):
        shape = shape_at(width, sensor_shape)
        tg = targets(make(shape))["spinnaker1"]
        if tg["boards_spinn5"] == 1 and not tg["violations"]:
            return {
                "width": width,
                "height": shape[0],
                "cores": tg["cores"],
                "chips": tg["chips"],
                "board_cores": board,
                "widths_searched": [min(cores), max(cores)],
                "narrower_not_fitting": sorted(w for w, c in cores.items() if w < width and c > board),
            }
    return None


def one_board_lines(one: dict) -> list[str]:
    """The report's lines on :func:`widest_on_one_board`'s answer."""
    lo, hi = one["widths_searched"]
    lines = [
        f"one board holds at most a {one['width']} x {one['height']} sensor ({one['cores']} of its "
        f"{one['board_cores']} cores, {one['chips']} chips): the widest of every width {lo}-{hi} counted "
        f"(wider ones need more than {one['board_cores']} cores for their cells alone)"
    ]
    narrower = one["narrower_not_fitting"]
    if narrower:
        lines.append(
            "fit is not monotonic in size (cores: grid sides with few divisors cut into more tiles): "
            f"narrower, {'width' if len(narrower) == 1 else 'widths'} {width_ranges(narrower)} "
            f"{'does' if len(narrower) == 1 else 'do'} not fit"
        )
    return lines
