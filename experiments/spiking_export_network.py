"""Write every file of networks/: the default network description for the BSDS
frame size, and the default iCub-size (304 x 240) network as a NIR graph with
its hardware resource report (snn_fg.export.artefacts).

networks/default_321x481.json is the description ``build_network(ModelParams(),
(321, 481), SpikingParams())`` produces: every population, projection (kernel
references, gains, delays) and neuron constant. Re-run after changing the
defaults (tests/test_network_description.py checks the stored file is current).

    python experiments/spiking_export_network.py      (or python -m experiments.spiking_export_network)

Not an experiment: it measures nothing, it regenerates files the tests check.
"""

from pathlib import Path

from snn_fg.network import SpikingParams, build_network
from snn_fg.params import ModelParams

ROOT = Path(__file__).resolve().parents[1]


def main():
    net = build_network(ModelParams(), (321, 481), SpikingParams())
    path = net.save(ROOT / "networks" / "default_321x481.json")
    print(net.summary().splitlines()[0])
    print(f"wrote {path}")
    from snn_fg.export.artefacts import write_artefacts

    for path in write_artefacts(ROOT / "networks"):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
