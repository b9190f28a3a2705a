"""Our models against references and against each other: the rate model against the authors' outputs,
the spiking network against the rate model, the human labels and other simulators, on frames and
recordings. See experiments/README.md."""
