"""Networks by name: :data:`RECIPES` and :func:`network_for`.

A recipe is the model's parameters and the spiking constants that make one
kind of network; it is built for the size of whatever input it meets
(:meth:`Recipe.build`), so ``--network compact`` runs on a 304 x 240 ATIS,
a 346 x 260 DAVIS or an image alike.

* ``default``: the model as the paper gives it (``ModelParams()``,
  ``SpikingParams()``), the network every fidelity result is about.
* ``compact``: the same stages in a form that fits one Loihi 2 chip at the
  iCub's 304 x 240 and aims at real time on one CPU core: the sensor pooled
  3 x 3, an input that passes on one event of a block per 60 ms,
  octave-spaced levels, excess cells on the grouping lattice, a stronger
  window clock, a 1 ms time step and kernels pruned at 30 % (DoG) and 20 % (von Mises)
  of their peak.
  ``docs/model.md`` ("The compact network") gives each choice with what it
  saves and costs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .. import validate as check
from ..errors import InputError
from ..frames.pool import pooled_shape
from ..frames.pyramid import check_levels
from ..params import ModelParams
from .builder import build_network
from .graph import Network
from .spiking_params import SpikingParams


@dataclass(frozen=True)
class Recipe:
    """A named kind of network: model parameters and spiking constants."""

    name: str
    summary: str
    params: ModelParams
    spiking: SpikingParams

    def build(self, sensor_shape) -> Network:
        """The network for a sensor (or image) of ``sensor_shape`` (rows, cols)."""
        shape = pooled_shape(
            check.shape2(f"recipe {self.name!r}", "sensor_shape", sensor_shape), self.params.input_pool
        )
        check_levels(shape, self.params.levels, f"recipe {self.name!r}", self.params.levels_per_octave)
        return build_network(self.params, shape, self.spiking)


def _unchanged(x):
    return x


@dataclass(frozen=True, kw_only=True)
class Lever:
    """One departure of the compact network from the default: a name, what
    it does, and how it changes the model parameters (``params``) and the
    spiking constants (``spiking``), each a function of what it changes."""

    name: str
    does: str
    params: Callable[[ModelParams], ModelParams] = _unchanged
    spiking: Callable[[SpikingParams], SpikingParams] = _unchanged

    def apply(self, recipe: Recipe) -> Recipe:
        return Recipe(recipe.name, recipe.summary, self.params(recipe.params), self.spiking(recipe.spiking))


#: the default network's constants, which a lever's words give in brackets beside its own
_DEFAULT = SpikingParams()

#: The compact network's values, each written once: its levers' words and changes are made from them
POOL, POOLED_R0, POOLED_LEVELS = 3, 4.0, 7  # (R0 in blocks)
INPUT_REFRACTORY_MS = 60.0
OCTAVE_LEVELS = 3
EXCESS_STRIDE = 2
PRUNE_RESIZE = 0.01
CLOCK_INH_GROUP = 1400.0
DT_MS = 1.0
PRUNE_DOG, PRUNE_VM = 0.3, 0.2

#: the time steps of the named networks, as a help text says them
TIME_STEPS_TEXT = f"the network's: {_DEFAULT.time.dt_ms:g} ms, the compact network {DT_MS:g} ms"

#: The compact network's departures from the default, in the order
#: ``docs/model.md`` ("The compact network") measures them one after the other.
COMPACT_LEVERS = (
    Lever(
        name="pooled input",
        does=(
            f"the sensor pooled {POOL} x {POOL} before stage 1 (the model sees blocks), "
            f"R0 = {POOLED_R0:g} blocks ({POOLED_R0 * POOL:g} px)"
        ),
        params=lambda p: p.replace(input_pool=POOL, r0=POOLED_R0, levels=POOLED_LEVELS),
    ),
    Lever(
        name="input refractory period",
        does=f"a block and polarity passes on one event per {INPUT_REFRACTORY_MS:g} ms",
        spiking=lambda s: s.replace(input=s.input.replace(input_refractory_ms=INPUT_REFRACTORY_MS)),
    ),
    Lever(
        name="octave levels",
        does=f"{OCTAVE_LEVELS} levels an octave apart (1/2, not 1/sqrt(2))",
        params=lambda p: p.replace(levels_per_octave=1, levels=OCTAVE_LEVELS),
    ),
    Lever(
        name="excess cells on the grouping lattice",
        does=f"one excess cell per {EXCESS_STRIDE} x {EXCESS_STRIDE} block of border-ownership cells",
        spiking=lambda s: s.replace(connectivity=s.connectivity.replace(excess_stride=EXCESS_STRIDE)),
    ),
    Lever(
        name="8-bit interpolation weights",
        does=f"Resize products under {100 * PRUNE_RESIZE:g} % of their peak left out",
        spiking=lambda s: s.replace(connectivity=s.connectivity.replace(prune_resize=PRUNE_RESIZE)),
    ),
    Lever(
        name="stronger window clock",
        does=(
            f"the window clock puts {CLOCK_INH_GROUP:g} thresholds on the grouping cells "
            f"({_DEFAULT.gains.clock_inh_group:g})"
        ),
        spiking=lambda s: s.replace(gains=s.gains.replace(clock_inh_group=CLOCK_INH_GROUP)),
    ),
    Lever(
        name="1 ms time step",
        does=f"stepped at {DT_MS:g} ms, SpiNNaker's own time step ({_DEFAULT.time.dt_ms:g} ms)",
        spiking=lambda s: s.replace(time=s.time.replace(dt_ms=DT_MS)),
    ),
    Lever(
        name="pruned kernels",
        does=(
            f"DoG taps under {100 * PRUNE_DOG:g} % and von Mises taps under {100 * PRUNE_VM:g} % of the kernel's "
            f"peak left out ({100 * _DEFAULT.connectivity.prune_dog:g} %)"
        ),
        spiking=lambda s: s.replace(connectivity=s.connectivity.replace(prune_dog=PRUNE_DOG, prune_vm=PRUNE_VM)),
    ),
)


def _compact() -> Recipe:
    r = Recipe(
        "compact", "deployment form: " + "; ".join(lv.does for lv in COMPACT_LEVERS), ModelParams(), SpikingParams()
    )
    for lever in COMPACT_LEVERS:
        r = lever.apply(r)
    return r


RECIPES: dict[str, Recipe] = {
    "default": Recipe(
        "default",
        "the model as published: 10 levels 1/sqrt(2) apart, 8 orientations, R0 = 8 px",
        ModelParams(),
        SpikingParams(),
    ),
    "compact": _compact(),
}


def is_recipe(network) -> bool:
    """Whether ``network`` names a recipe (rather than a file or a Network)."""
    return isinstance(network, str) and network in RECIPES


def network_for(network, sensor_shape) -> tuple[Network, dict]:
    """The description for a sensor of ``sensor_shape`` (rows, cols) from a
    recipe name, a stored description (path) or a :class:`Network`, and how
    it was obtained (for the record). A stored description is resized to
    the sensor (its pooled frame when its ``input_pool > 1``)."""
    if is_recipe(network):
        return RECIPES[network].build(sensor_shape), {"origin": "recipe", "recipe": network}
    origin = {"origin": "given"}
    if isinstance(network, (str, Path)):
        origin = {"origin": str(network)}
        network = load_description(network)
    if not isinstance(network, Network):
        check.fail(
            "network",
            None,
            type(network).__name__,
            f"must be a recipe name ({', '.join(RECIPES)}), a Network or a path to its JSON",
        )
    shape = pooled_shape(check.shape2("network", "sensor_shape", sensor_shape), network.params.input_pool)
    if network.frame_shape != tuple(shape):
        origin["resized_from"] = list(network.frame_shape)
        network = network.resized(shape)
    return network, origin


def model_params_of(network) -> ModelParams:
    """The model parameters a recipe or a stored description carries (for the rate model)."""
    if is_recipe(network):
        return RECIPES[network].params
    if isinstance(network, Network):
        return network.params
    return load_description(network).params


def load_description(path) -> Network:
    """A stored description; a name that is neither a recipe nor a file is
    refused with the recipes' names (a mistyped ``--network compcat``)."""
    if not isinstance(path, (str, Path)):
        raise InputError(
            f"<{type(path).__name__}>",
            f"a network is a name ({', '.join(RECIPES)}), a stored description's path (.json) or a Network",
        )
    if not Path(path).exists():
        if str(path).endswith(".json"):
            raise InputError(
                path, f"no such file (from {Path.cwd()}); a stored description's path is taken from the current folder"
            )
        raise InputError(path, f"neither a network name ({', '.join(RECIPES)}) nor a stored description (.json)")
    net = Network.load(path)
    fault = net.readout_fault()  # (checked here, not part way through a run or after an export)
    if fault is not None:
        raise InputError(
            path,
            f"cannot be run and decoded (params.levels={net.params.levels}): {fault} for the decoder (levels "
            "edited without the populations? snn-fg export --format network --levels N writes a network of N)",
        )
    return net
