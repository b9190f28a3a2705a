"""Write the default network description for the BSDS frame size to networks/.

networks/default_321x481.json is the description ``build_network(ModelParams(),
(321, 481), SpikingParams())`` produces: every population, projection (kernel
references, gains, delays) and neuron constant. Re-run after changing the
defaults (tests/test_network_description.py checks the stored file is current).
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from snn_fg.network import SpikingParams, build_network  # noqa: E402
from snn_fg.params import ModelParams  # noqa: E402


def main():
    net = build_network(ModelParams(), (321, 481), SpikingParams())
    path = net.save(ROOT / "networks" / "default_321x481.json")
    print(net.summary().splitlines()[0])
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
