"""NEST on 1 and 2 threads (local_num_threads), the spiking network on a disc
(radius 32, 10 levels), alternating 1, 2, 1, 2 to see the machine's noise.
Prints the backend's timings and the load average; writes
experiments/results/nest_threads.json. The nest-simulator wheel has no MPI
(nest.build_info["have_mpi"] is False), so processes cannot be measured here.
Usage: python experiments/nest_threads.py
"""
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from snn_fg.atomic import save_text  # noqa: E402
from snn_fg.events import image_to_frame  # noqa: E402
from snn_fg.scenes import disc  # noqa: E402
from snn_fg.spiking import run_spiking_result  # noqa: E402


def main():
    pos, neg = image_to_frame(disc(32).image)
    rows = []
    for threads in (1, 2, 1, 2):
        t0 = time.perf_counter()
        r = run_spiking_result(pos, neg, backend="nest", backend_options={"threads": threads}, progress=False,
                               record_spikes=False)
        rows.append({"threads": threads, "wall_s": time.perf_counter() - t0, "timings_s": r.result.timings_s,
                     "load": os.getloadavg()})
        print(json.dumps(rows[-1]), flush=True)
    import nest

    save_text(ROOT / "experiments" / "results" / "nest_threads.json",
              json.dumps({"have_mpi": bool(nest.build_info["have_mpi"]), "runs": rows}, indent=1))


if __name__ == "__main__":
    main()
