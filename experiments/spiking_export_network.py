"""Write the default network description for the BSDS frame size to networks/.

networks/default_321x481.json is the declarative description (populations,
projections with kernel references, neuron constants, gains, delays) that
``snn_fg.network.description.build_network(ModelParams(), (321, 481),
NetworkParams())`` produces; networks/default_321x481.network_params.json holds
the NetworkParams it was built with. Re-run after changing the defaults
(tests/test_network_description.py checks that the stored file is current).
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from snn_fg.atomic import save_text  # noqa: E402
from snn_fg.network.description import NetworkParams, build_network  # noqa: E402
from snn_fg.params import ModelParams  # noqa: E402


def main():
    np_ = NetworkParams()
    net = build_network(ModelParams(), (321, 481), np_)
    out = ROOT / "networks"
    save_text(out / "default_321x481.json", net.to_json(indent=1) + "\n")
    save_text(out / "default_321x481.network_params.json", json.dumps(np_.to_dict(), indent=1, sort_keys=True) + "\n")
    print(net.summary().splitlines()[0])
    print(f"wrote {out / 'default_321x481.json'}")


if __name__ == "__main__":
    main()
