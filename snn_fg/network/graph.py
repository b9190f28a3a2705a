"""A network description as one validated graph: :class:`Network`.

The graph is what every simulator backend and every exporter consumes, and
what ``networks/*.json`` stores: a user can edit a stored description (a gain,
a delay, a time constant) and run it with ``snn-fg run INPUT --model spiking
--network FILE.json``.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

from .. import validate as check
from ..errors import InputError, ParameterError
from ..frames.pyramid import level_shape
from ..params import ModelParams
from ..results.atomic import save_text
from .nodes import Population
from .projections import Conv, Projection, projection_from_dict
from .roles import READOUT_ROLES

#: how a recording's events become input spikes (:attr:`Network.input_coding`)
INPUT_CODINGS = ("events", "window", "sliding")
#: the codings that hold each pixel's last polarity (:mod:`snn_fg.lowering.held_input`)
HELD_CODINGS = ("window", "sliding")

SCHEMA = "snn-fg.network/2"
#: the time step (ms) of a network that does not name one: the one default of the package's time step (a
#: recipe's ``SpikingParams.dt_ms``, a stored description without ``dt_ms``); a run or an export takes the
#: network's own step unless told otherwise (:meth:`Network.time_step`)
DEFAULT_DT_MS = 0.5
#: the input a network is made for unless told otherwise (each described in
#: :class:`~snn_fg.network.spiking_params.Input`, whose defaults they are): the
#: rate of an input pixel with events that its gains are set for, which is also
#: the rate of an event frame's regular trains (``snn-fg run``'s, an export's
#: input); which coarse cells exist (``support_min``, ``drive_min``); the input
#: adapter's refractory period (0: every event a spike)
INPUT_RATE_HZ, SUPPORT_MIN, DRIVE_MIN, INPUT_REFRACTORY_MS = 200.0, 0.3, 0.85, 0.0


#: a :class:`Network`'s settings: its fields other than its parameters, frame, cells, wiring and notes
SETTINGS = ("input_rate_hz", "support_min", "drive_min", "input_refractory_ms", "input_coding", "one_grid", "dt_ms")


def _not_one(role: str, level: int, found: int) -> str:
    """The one wording of a level without exactly one population of ``role``."""
    return f"level {level} has {found} populations of role {role!r}, need exactly 1"


def _grid_shape(pop, frame_shape, per_octave: int, one_grid: bool = False) -> tuple[int, int]:
    """The ``level_shape`` a population must have for frames of
    ``frame_shape``: its pyramid level's (the frame's on one grid), except
    the one-cell window clock's."""
    if pop.role == "clock":
        return (1, 1)
    return tuple(frame_shape) if one_grid else level_shape(frame_shape, pop.level, per_octave)


@dataclass(frozen=True, kw_only=True)
class Network:
    """A validated network graph for frames of ``frame_shape`` (rows, cols).

    ``params`` are the model parameters the kernels are made from.
    ``input_rate_hz`` is the mean input rate per active pixel that the gains
    of the ``calibrated`` projections are set for (see :meth:`calibrated`).
    ``support_min`` and ``drive_min`` parametrise the instantiation hints of
    the populations (:data:`~snn_fg.network.nodes.SITE_RULES`).
    ``input_refractory_ms``: the input adapter passes an event of a spike
    source (a pixel, or a block of them, and a polarity) on only this long
    after the last one it passed on (0: every event is a spike), so that a
    busy source fires like a quiet one. ``input_coding``: how a recording's
    events become spikes, ``events`` (each event one spike at its time,
    through the refractory period), ``window`` (the window's event frame
    built as they arrive, cleared as each window starts:
    :mod:`snn_fg.lowering.held_input`) or ``sliding`` (each pixel's last
    polarity held for one window's length after its event, never cleared
    at a window's edge: at each window's end the window's event frame, in
    between the frame of the last window's length); a frame's
    pixels fire regular trains either way. ``one_grid``: every pyramid level
    lies on the frame's grid (its kernels dilated by the level's scale; a
    form for NIR consumers that cannot interpolate between levels,
    :func:`~snn_fg.export.nir_snntorch.one_grid_network`). ``dt_ms``: the
    time step the network is made for, which runs and exports use unless
    told otherwise (its delays and refractory periods are whole steps of
    it). ``notes`` document the network (its departures from the rate model).
    """

    params: ModelParams
    frame_shape: tuple[int, int]
    populations: tuple[Population, ...]
    projections: tuple[Projection, ...]
    input_rate_hz: float = INPUT_RATE_HZ
    support_min: float = SUPPORT_MIN
    drive_min: float = DRIVE_MIN
    input_refractory_ms: float = INPUT_REFRACTORY_MS
    input_coding: str = "events"
    one_grid: bool = False
    dt_ms: float = DEFAULT_DT_MS
    notes: tuple[str, ...] = ()
    _by_name: dict = field(init=False, repr=False, compare=False, hash=False)

    def __post_init__(self):
        owner = "Network"
        if not isinstance(self.params, ModelParams):
            check.fail(owner, "params", type(self.params).__name__, "must be a ModelParams")
        object.__setattr__(self, "frame_shape", check.shape2(owner, "frame_shape", self.frame_shape))
        for name in ("populations", "projections", "notes"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(
            self, "input_rate_hz", check.number(owner, "input_rate_hz", self.input_rate_hz, lo=0, lo_open=True)
        )
        object.__setattr__(self, "support_min", check.number(owner, "support_min", self.support_min, lo=0))
        object.__setattr__(self, "drive_min", check.number(owner, "drive_min", self.drive_min, lo=0))
        object.__setattr__(
            self, "input_refractory_ms", check.number(owner, "input_refractory_ms", self.input_refractory_ms, lo=0)
        )
        check.choice(owner, "input_coding", self.input_coding, INPUT_CODINGS)
        object.__setattr__(self, "one_grid", check.flag(owner, "one_grid", self.one_grid))
        object.__setattr__(self, "dt_ms", check.number(owner, "dt_ms", self.dt_ms, lo=0, lo_open=True))
        object.__setattr__(self, "_by_name", self._check_populations())
        self._check_projections()

    def _check_populations(self) -> dict:
        pops = {}
        for p in self.populations:
            if not isinstance(p, Population):
                check.fail("Network", "populations", type(p).__name__, "must hold Population nodes")
            owner = f"Population '{p.name}'"
            if p.name in pops:
                check.fail(owner, None, None, "name used twice")
            if p.level > self.params.levels:
                check.fail(owner, "level", p.level, f"exceeds params.levels={self.params.levels}")
            want = _grid_shape(p, self.frame_shape, self.params.levels_per_octave, self.one_grid)
            if p.level_shape != want:
                check.fail(
                    owner,
                    "level_shape",
                    p.level_shape,
                    f"differs from level {p.level} of a {self.frame_shape} frame, {want}",
                )
            pops[p.name] = p
        for p in self.populations:
            for q in p.site_sources:
                if q not in pops:
                    check.fail(f"Population '{p.name}'", "site_sources", q, "is not a population")
        return pops

    def _check_projections(self):
        names = set()
        for pr in self.projections:
            if not isinstance(pr, Projection):
                check.fail("Network", "projections", type(pr).__name__, "must hold Projection nodes")
            owner = pr._owner
            if pr.name in names or pr.name in self._by_name:
                check.fail(owner, None, None, "name used twice")
            names.add(pr.name)
            for end in ("source", "target"):
                if getattr(pr, end) not in self._by_name:
                    check.fail(owner, end, getattr(pr, end), "is not a population")
            src, tgt = self._by_name[pr.source], self._by_name[pr.target]
            if tgt.is_source:
                check.fail(owner, "target", tgt.name, "is a spike source and cannot receive connections")
            if isinstance(pr, Conv):
                self._check_conv(pr, src, tgt)
            elif src.channels != tgt.channels:
                check.fail(
                    owner,
                    None,
                    None,
                    f"source '{src.name}' has {src.channels} channels, target "
                    f"'{tgt.name}' {tgt.channels}; a Resize maps channel to channel",
                )

    def _check_conv(self, pr: Conv, src: Population, tgt: Population):
        owner = pr._owner
        if src.level != tgt.level and not self.one_grid:  # on one grid every level has the frame's pixels
            check.fail(
                owner,
                None,
                None,
                f"source '{src.name}' (level {src.level}) and target '{tgt.name}' "
                f"(level {tgt.level}) must share a level; use a Resize between levels",
            )
        k = pr.kernel.array(self.params)
        for axis, pop, end in ((0, tgt, "output"), (1, src, "input")):
            if k.shape[axis] != pop.channels:
                check.fail(
                    owner, None, None, f"kernel has {k.shape[axis]} {end} channels but '{pop.name}' has {pop.channels}"
                )
        if pr.padding == "wrap" and (src.stride != 1 or tgt.stride != 1):
            check.fail(owner, "padding", "wrap", "needs stride 1 on both ends")

    # -- lookups ---------------------------------------------------------
    def population(self, name: str) -> Population:
        try:
            return self._by_name[name]
        except KeyError:
            check.fail("Network", None, None, f"has no population named {name!r}")

    def by_role(self, role: str, level: int | None = None) -> list[Population]:
        return [p for p in self.populations if p.role == role and (level is None or p.level == level)]

    def one(self, role: str, level: int) -> Population:
        """The population of ``role`` at ``level`` (exactly one must exist)."""
        found = self.by_role(role, level)
        if len(found) != 1:
            check.fail("Network", None, None, _not_one(role, level, len(found)))
        return found[0]

    def readout_fault(self) -> str | None:
        """Why the decoder could not read this network's spikes (a level of ``params.levels``
        without exactly one population of each of :data:`.roles.READOUT_ROLES`), or None."""
        for level in range(1, self.params.levels + 1):
            for role in READOUT_ROLES:
                found = len(self.by_role(role, level))
                if found != 1:
                    return _not_one(role, level, found)
        return None

    def incoming(self, name: str) -> list[Projection]:
        return [pr for pr in self.projections if pr.target == name]

    def outgoing(self, name: str) -> list[Projection]:
        return [pr for pr in self.projections if pr.source == name]

    @property
    def sources(self) -> list[Population]:
        return [p for p in self.populations if p.is_source]

    def time_step(self, dt_ms: float | None = None, owner: str = "Network.time_step") -> float:
        """The time step (ms) of a run or an export of this network: ``dt_ms``
        when given (checked: above 0; ``owner`` names the caller in the
        error), else the network's own :attr:`dt_ms`."""
        return self.dt_ms if dt_ms is None else check.number(owner, "dt_ms", dt_ms, lo=0, lo_open=True)

    # -- derived networks --------------------------------------------------
    def calibrated(self, input_rate_hz: float) -> Network:
        """The same network with its ``calibrated`` gains set for another input rate.

        A projection marked ``calibrated`` carries input-rate-proportional
        activity (from the spike sources, or from cells whose rate follows
        theirs); its gain is scaled by ``input_rate_hz / new rate`` so that
        the mean currents it delivers stay the same.
        """
        rate = check.number("Network.calibrated", "input_rate_hz", input_rate_hz, lo=0, lo_open=True)
        factor = self.input_rate_hz / rate
        prjs = tuple(
            dataclasses.replace(pr, gain_mv=pr.gain_mv * factor) if pr.calibrated else pr for pr in self.projections
        )
        return dataclasses.replace(self, projections=prjs, input_rate_hz=rate)

    def without_feedback(self) -> Network:
        """The same network without the feedback onto border-ownership cells
        (the ablation of stage 8: both sides of every border stay equal)."""

        def feedback(pr):
            return self.population(pr.source).role.startswith("feedback") and self.population(
                pr.target
            ).role.startswith("bo_")

        return dataclasses.replace(self, projections=tuple(pr for pr in self.projections if not feedback(pr)))

    def resized(self, frame_shape) -> Network:
        """The same network for frames of another shape (kernels are weight
        shared, so only the populations' level shapes change)."""
        shape = check.shape2("Network.resized", "frame_shape", frame_shape)
        per_octave = self.params.levels_per_octave
        pops = tuple(
            dataclasses.replace(p, level_shape=_grid_shape(p, shape, per_octave, self.one_grid))
            for p in self.populations
        )
        return dataclasses.replace(self, frame_shape=shape, populations=pops)

    # -- serialisation -----------------------------------------------------
    def settings(self) -> dict:
        """The network's own settings, every one: what a format that carries the cells and their
        wiring its own way (NIR) stores beside them, so that reading it back gives this network."""
        return {name: getattr(self, name) for name in SETTINGS}

    def to_dict(self) -> dict:
        # input_coding, one_grid and dt_ms only when not the default: the stored descriptions (and their
        # fingerprints) stay as they were
        optional = {"input_coding": "events", "one_grid": False, "dt_ms": DEFAULT_DT_MS}
        return {
            "schema": SCHEMA,
            "params": self.params.to_dict(),
            "frame_shape": list(self.frame_shape),
            **{k: v for k, v in self.settings().items() if k not in optional or v != optional[k]},
            "notes": list(self.notes),
            "populations": [p.to_dict() for p in self.populations],
            "projections": [pr.to_dict() for pr in self.projections],
        }

    @classmethod
    def from_dict(cls, d: dict) -> Network:
        if not isinstance(d, dict):
            check.fail("Network", None, None, f"expected a mapping, got {type(d).__name__}")
        if d.get("schema") != SCHEMA:
            check.fail("Network", "schema", d.get("schema"), f"is not {SCHEMA!r}")
        fields = {"params", "frame_shape", *SETTINGS, "notes", "populations", "projections"}
        check.known_keys("Network", set(d) - {"schema"}, fields)
        missing = sorted({"params", "frame_shape", "populations", "projections"} - set(d))
        if missing:
            check.fail("Network", None, None, f"lacks field(s) {', '.join(missing)}")
        kw = {k: d[k] for k in fields if k in d}
        kw["params"] = ModelParams.from_dict(d["params"])
        kw["populations"] = tuple(Population.from_dict(p) for p in d["populations"])
        kw["projections"] = tuple(projection_from_dict(p) for p in d["projections"])
        return cls(**kw)

    def to_json(self, indent: int | None = 1) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_json(cls, text: str) -> Network:
        return cls.from_dict(json.loads(text))

    def save(self, path) -> Path:
        """Write the description as JSON (atomically)."""
        return save_text(path, self.to_json() + "\n")

    @classmethod
    def load(cls, path) -> Network:
        """Read a description written by :meth:`save` (or edited by hand).

        Any problem is an :class:`~snn_fg.errors.InputError` naming the file
        and, for an invalid description, the node at fault.
        """
        path = Path(path)
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise InputError(path, "no such file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(path, f"cannot read the network description ({exc})") from None
        try:
            return cls.from_json(text)
        except json.JSONDecodeError as exc:
            raise InputError(path, f"not JSON: {exc.msg}", f"line {exc.lineno}, column {exc.colno}") from None
        except ParameterError as exc:
            raise InputError(path, f"invalid network description: {exc}") from None

    def summary(self) -> str:
        lines = [
            f"Network for a {self.frame_shape[0]} x {self.frame_shape[1]} frame, "
            f"{self.params.levels} levels: {len(self.populations)} populations, "
            f"{len(self.projections)} projections"
        ]
        for p in self.populations:
            lines.append(
                f"  {p.name:14s} {p.role:12s} level {p.level:2d} grid {p.grid} x{p.channels} "
                f"stride {p.stride} sites={p.sites}"
            )
        return "\n".join(lines)
