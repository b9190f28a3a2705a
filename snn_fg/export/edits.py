"""Whether an export's ``network.json`` still says what the description it embeds says.

An export's ``network.json`` holds the network twice: the populations and projections its
``run.py`` builds (``populations``, ``projections``), and the snn-fg description they were
derived from (``snn_fg_network``), which ``snn-fg decode`` reads. A user who edits the first
(a gain, say) runs the edited network on the board, while snn-fg still sees the embedded one.
:func:`export_edits` derives the entries again from the embedded description, as the export
did (:func:`~snn_fg.export.folder.population_entry`,
:func:`~snn_fg.export.folder.projection_entry` and the format's own fields), and names every
field that differs. What a projection's table gives (its kept taps, synapse count) is left out:
deriving it takes seconds, and the tables are written in ``tables.npz``, not edited by hand.
"""

from __future__ import annotations

import json
from typing import NamedTuple

from ..errors import InputError
from ..network.graph import Network
from . import lava, pynn
from .folder import population_entry, projection_entry

#: what decoding reads of a population: the names, sizes and grids that place run.py's counts
LAYOUT_KEYS = ("name", "role", "level", "size", "level_shape", "grid", "stride", "channels")
#: how many differing fields a message names
SHOWN = 3


class Edit(NamedTuple):
    """One field of ``network.json`` that differs from what the embedded description gives."""

    kind: str  # "population" or "projection"
    name: str
    key: str  # "" for an entry the one has and the other has not
    derived: object  # what the embedded description gives (None: no such entry)
    held: object  # what the file holds (None: no such entry)

    def __str__(self) -> str:
        if not self.key:
            return f"{self.kind} {self.name} {'absent' if self.held is None else 'added'}"
        return f"{self.kind} {self.name} {self.key} {json.dumps(self.derived)} -> {json.dumps(self.held)}"

    @property
    def layout(self) -> bool:
        """Whether decoding reads it (a population's name, size or grid; a population added or absent)."""
        return self.kind == "population" and (not self.key or self.key in LAYOUT_KEYS)


def _extras(net: Network, meta: dict):
    """The format's own fields of ``network.json``'s entries (by its ``schema``)."""
    schema = meta.get("schema")
    if schema == lava.SCHEMA:
        return lava.entry_extras(net)
    if schema == pynn.SCHEMA:
        return pynn.entry_extras(net, meta.get("weight_bits"))
    return None, None


def _compare(kind: str, derived: list, held, edits: list) -> None:
    held = {e.get("name"): e for e in held if isinstance(e, dict)} if isinstance(held, list) else {}
    names = {e["name"] for e in derived}
    for d in derived:
        h = held.get(d["name"])
        if h is None:
            edits.append(Edit(kind, d["name"], "", d, None))
            continue
        # (a field the file lacks, as an export of an earlier snn-fg may, is no edit)
        edits.extend(Edit(kind, d["name"], k, v, h[k]) for k, v in d.items() if k in h and h[k] != v)
    edits.extend(Edit(kind, str(n), "", None, h) for n, h in held.items() if n not in names)


def export_edits(net: Network, meta: dict) -> list[Edit]:
    """The fields of an export's ``network.json`` (``meta``) whose populations and projections
    differ from what its embedded description ``net`` (the board network) gives, in file order
    (none: the file says what the description says)."""
    population_extra, projection_extra = _extras(net, meta)

    def proj(pr):
        return {**projection_entry(pr), **(projection_extra(pr) if projection_extra else {})}

    # (through JSON, as the file went: tuples become lists)
    pops = json.loads(json.dumps([population_entry(p, population_extra) for p in net.populations]))
    prjs = json.loads(json.dumps([proj(pr) for pr in net.projections]))
    edits: list[Edit] = []
    _compare("population", pops, meta.get("populations"), edits)
    _compare("projection", prjs, meta.get("projections"), edits)
    return edits


def edits_text(edits: list[Edit]) -> str:
    """The first :data:`SHOWN` of ``edits``, and how many more, in words."""
    more = f" and {len(edits) - SHOWN} more" if len(edits) > SHOWN else ""
    return ", ".join(str(e) for e in edits[:SHOWN]) + more


#: what to do to run an edited network, and have snn-fg see the same one
REDO = (
    "to change the network, edit the description the export was made from (a copy of "
    "networks/compact_304x240.json, or what snn-fg export --format network --out net.json writes) and export it "
    "again with --network net.json (networks/README.md says what each field means)"
)


def checked_export(path, net: Network, meta: dict, reference: str | None, done: str = "decoded with") -> str | None:
    """Whether ``snn-fg decode`` (and ``snn-fg events --write-spikes``, ``done`` saying what it does
    with the description) may use an export whose ``network.json`` is ``path``.

    With ``reference`` (a backend) any edit is refused: the reference runs the embedded
    description, and its agreement line would call that the network run.py ran. Without, an
    edit decoding does not read (a gain, a delay, a neuron constant) leaves the decoding right:
    run.py's counts are placed by the populations' names, sizes and grids, which it leaves
    alone; the line returned (None: no edit) says so. An edit of those is refused either way.
    Refusals are one :class:`~snn_fg.errors.InputError` line naming the first fields."""
    edits = export_edits(net, meta)
    if not edits:
        return None
    layout = [e for e in edits if e.layout]
    if layout:
        raise InputError(
            path,
            f"its populations differ from the snn-fg description it embeds (snn_fg_network), whose layout "
            f"places run.py's counts: {edits_text(layout)}; {REDO}",
        )
    if reference:
        raise InputError(
            path,
            f"differs from the snn-fg description it embeds (snn_fg_network), which --reference {reference} "
            f"runs: {edits_text(edits)}, so the reference would not be of the network run.py ran; {REDO}",
        )
    return (
        f"snn-fg: note: {path} differs from the snn-fg description it embeds: {edits_text(edits)}; {done} "
        "the embedded description's populations (names, sizes, grids), which these leave as they are"
    )
