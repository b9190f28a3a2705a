"""``snn-fg data``: list the datasets, show one, fetch one.

Wire it in with :func:`add_data_command`; a failure raises
:class:`~snn_fg.datasets.DatasetError` (the main CLI prints it as one line
and exits non-zero).
"""

from __future__ import annotations

import argparse
import os

from .. import datasets
from .options import size_text, subcommand


def _status(name: str, check: bool) -> str:
    ds = datasets.get(name)
    gone = datasets.verify(name) if check else datasets.missing(name)
    if not gone:
        return "present, checksums match" if check else "present"
    if len(gone) == len(ds.files):
        return "absent"
    return f"incomplete: {len(gone)} of {len(ds.files)} files {'differ or are ' if check else ''}missing"


def cmd_list(args) -> int:
    root, origin = datasets.root_and_origin()
    chooses = "" if origin.endswith(datasets.ENV_VAR) else f"; ${datasets.ENV_VAR} chooses another"
    print(f"data folder: {root} ({origin}{chooses})")
    if not root.is_dir():  # (every dataset then shows absent: say why, not only that)
        print(f"  ({root} does not exist: snn-fg data fetch NAME makes it, or ${datasets.ENV_VAR} names another)")
    elif not os.access(root, os.W_OK):  # (a fetch there could never be written: said before it is tried)
        print(f"  ({root} cannot be written here: a fetch needs ${datasets.ENV_VAR} naming a folder you can write)")
    rows = [("name", "size", "status", "folder")]
    rows += [
        (name, size_text(ds.size), _status(name, args.verify), str(root / name))
        for name, ds in datasets.DATASETS.items()
    ]
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)) + "  " + r[3])
    return 0


def cmd_info(args) -> int:
    ds = datasets.get(args.name)
    if args.files:  # (one path a line, relative to the dataset's folder: what to put where by hand)
        print("\n".join(f.path for f in ds.files))
        return 0
    fetch = f"snn-fg data fetch {ds.name}" if ds.fetch else f"not available: {ds.unavailable}"
    for key, value in (
        ("dataset", ds.name),
        ("what", ds.description),
        ("files", f"{len(ds.files)}, {size_text(ds.size)}"),
        ("source", ds.source),
        ("licence", ds.licence),
        ("download", ds.download),
        ("fetch", fetch),
        ("folder", str(datasets.data_root() / ds.name)),
    ):
        print(f"{key + ':':<10}{value}")
    return 0


def cmd_fetch(args) -> int:
    made = datasets.fetch(args.name, progress=not args.no_progress)
    folder = datasets.data_root() / args.name
    print(
        f"{args.name}: {len(made)} files fetched and verified into {folder}"
        if made
        else f"{args.name}: already present in {folder}, checksums match"
    )
    return 0


def add_data_command(subparsers) -> argparse.ArgumentParser:
    """Register ``data`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        subparsers,
        "data",
        description="The datasets live in one data folder: $SNN_FG_DATA, else the shared "
        "data beside a source checkout, else the user data folder.",
    )
    sub = p.add_subparsers(dest="data_command", required=True, metavar="ACTION")
    q = sub.add_parser("list", allow_abbrev=False, help="each dataset: size, whether it is present, where")
    q.add_argument("--verify", action="store_true", help="check every file's checksum (slower)")
    q.set_defaults(handler=cmd_list)
    q = sub.add_parser("info", allow_abbrev=False, help="one dataset: what it is, source, licence, how to fetch it")
    q.add_argument("name", metavar="NAME", choices=sorted(datasets.DATASETS))
    q.add_argument(
        "--files", action="store_true", help="list the dataset's files instead, one path a line (under its folder)"
    )
    q.set_defaults(handler=cmd_info)
    q = sub.add_parser(
        "fetch", allow_abbrev=False, help="download a dataset from its public source, verified by checksum"
    )
    q.add_argument("name", metavar="NAME", choices=sorted(datasets.DATASETS))
    q.add_argument("--no-progress", action="store_true", help="no progress bar")
    q.set_defaults(handler=cmd_fetch)
    return p
