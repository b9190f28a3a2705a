"""NEST on 1 and 2 threads (local_num_threads), the spiking network on a disc
(radius 32, 10 levels), alternating 1, 2, 1, 2 to see the machine's noise.
Prints the backend's timings and the load average; writes
experiments/results/nest_threads.json. The nest-simulator wheel has no MPI
(nest.build_info["have_mpi"] is False), so processes cannot be measured here.
Usage: python -m experiments.bench.nest_threads
"""

import json
import time

from experiments.common import Run, load, save_json
from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.models.spiking import run_spiking_result


def main():
    pos, neg = image_to_frame(disc(32).image)
    run = Run()
    rows = []
    for threads in (1, 2, 1, 2):
        t0 = time.perf_counter()
        r = run_spiking_result(
            pos, neg, backend="nest", backend_options={"threads": threads}, progress=False, record_spikes=False
        )
        rows.append(
            {"threads": threads, "wall_s": time.perf_counter() - t0, "timings_s": r.result.timings_s, "load": load()}
        )
        print(json.dumps(rows[-1]), flush=True)
    import nest

    save_json("nest_threads", {"have_mpi": bool(nest.build_info["have_mpi"]), "runs": rows, "run": run.record()})


if __name__ == "__main__":
    main()
