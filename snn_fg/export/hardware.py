"""Documented limits of the neuromorphic targets, each with where it comes from.

The figures are those of ``docs/neuromorphic-targets.md`` (checked against
the packages' own code); figures marked approximate are secondary.
:mod:`.report` measures a network against them.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Limit:
    """One documented limit: its value, unit and source."""

    value: float
    unit: str
    source: str
    approximate: bool = False


SPINNAKER1 = {
    "neurons_per_core": Limit(256, "IF_curr_exp neurons", "sPyNNaker default max atoms per core (IF_curr_exp)"),
    "cores_per_chip": Limit(
        16,
        "application cores",
        "SpiNNMachine: 18 cores per chip; sPyNNaker keeps one for the monitor and one for its extra monitor",
    ),
    "cores_placed_per_chip": Limit(
        15,
        "network cores",
        "sPyNNaker 1!7.4.1 mapping our exports onto a virtual "
        "SpiNN-5 board: 14.0-15.8 of a chip's 16 free cores used "
        "(experiments/results/export_spinnaker.md)",
        True,
    ),
    "chips_per_board": Limit(48, "chips", "SpiNNMachine: SpiNN-5 board"),
    "gatherer_cores_per_board": Limit(
        1,
        "cores",
        "sPyNNaker: a DataSpeedUpPacketGatherer on each board's Ethernet chip "
        "(every mapping in experiments/results/export_spinnaker.json)",
    ),
    "boards_per_triad": Limit(
        3,
        "boards",
        "SpiNNMachine size_from_n_boards, as spalloc allocates: more than one board is a rectangle of triads",
    ),
    "sdram_per_chip": Limit(123e6, "bytes", "SpiNNMachine: about 123 MB SDRAM per chip", True),
    "bytes_per_synapse": Limit(4, "bytes", "sPyNNaker synaptic matrix: one 32-bit word per synapse", True),
    "delay_slots": Limit(
        32,
        "time steps",
        "sPyNNaker: 2^(14 - (8 neuron index bits + 1 synapse type bit)) for 256 neurons and 2 receptors",
    ),
    "delay_extension": Limit(8, "x on-core slots", "sPyNNaker delay_support_adder.py: delay extensions"),
    "weight_bits": Limit(16, "bits per receptor", "sPyNNaker get_weight_scales: 16-bit weights scaled per receptor"),
}

SPINNAKER2 = {
    "cores_per_chip": Limit(152, "cores", "SpiNNaker2 chip"),
    "memory_per_core": Limit(128 * 1024, "bytes", "SpiNNaker2: 128 KB local memory per PE"),
    "bytes_per_synapse": Limit(4, "bytes", "assumed: one 32-bit word per explicit synapse", True),
    "bytes_per_neuron": Limit(32, "bytes", "assumed: LIF state and parameters per neuron", True),
    "weight_bits": Limit(8, "bits", "py-spinnaker2 NIR path: weights scaled to int8"),
    "delays": Limit(1, "distinct delay", "py-spinnaker2 NIR path: one delay for all projections"),
}

LOIHI2 = {
    "neurons_per_chip": Limit(1_000_000, "neurons", "Intel: about 1 M neurons per Loihi 2 chip", True),
    "synapses_per_chip": Limit(120_000_000, "synapses", "Intel: about 120 M synapses per Loihi 2 chip", True),
    "cores_per_chip": Limit(128, "neuro-cores", "Intel Loihi 2"),
    "neurons_per_core": Limit(8192, "neurons", "Loihi 2: up to about 8 k neurons per core", True),
    "weight_bits": Limit(8, "bits with a shared exponent", "Lava Conv process: num_weight_bits=8"),
    "delay_steps": Limit(62, "time steps", "lava-dl slayer block: delays up to 62 steps"),
    "synaptic_time_constants": Limit(1, "per neuron", "Lava LIF process: one current decay (du) per neuron"),
}

TARGETS = {"spinnaker1": SPINNAKER1, "spinnaker2": SPINNAKER2, "loihi2": LOIHI2}
