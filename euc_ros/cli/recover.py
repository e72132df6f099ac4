"""`euc-ros recover BAG`: rebuild a readable bag from a damaged one (recorder killed, metadata lost).

Reads every complete chunk of the bag's MCAP file(s), also when the file is truncated (no summary,
no footer) or metadata.yaml is missing or broken, and writes a new, complete bag (MCAP with summary
and a fresh metadata.yaml) next to it, ``BAG_recovered`` by default. The input is never modified.
It reports how many messages per topic were recovered and where reading stopped. A bag that a live
process still holds open (a recorder still writing it) is refused: it is not damaged, only unfinished.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import InputError
from euc_ros.core.io.bags import recover_bag
from euc_ros.core.io.open_files import processes_with_open

HELP = "rebuild a readable bag from a truncated or metadata-less one (recorder killed)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros recover``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
    """
    parser.add_argument("bag", help="damaged bag directory or .mcap file")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="new bag directory (must not exist; default: BAG_recovered next to BAG)")


def main(args: argparse.Namespace) -> int:
    """Recover; 0 when messages were recovered (InputError: exit 2 via the dispatcher)."""
    src = Path(args.bag)
    if not src.exists():
        raise InputError("no such file or directory", path=src)
    writers = processes_with_open(src)
    if writers:
        who = ", ".join(f"{name} (pid {pid})" for pid, name in writers)
        raise InputError(f"is still open in {who}: a bag being recorded is not damaged; stop the recorder "
                         f"(Ctrl-C in its terminal, or kill -INT {writers[0][0]}) and it closes the bag itself; "
                         f"recover bags whose recorder has died", path=src)
    standalone = src.is_file()
    out = Path(args.out) if args.out else src.with_name((src.stem if standalone else src.name) + "_recovered")
    if out.exists():
        raise InputError("exists already, not overwriting: give --out DIR", path=out)
    check_outputs([Output("--out", out, "dir")], [src])
    info = recover_bag(src, out)
    topics = ", ".join(f"{t}={n}" for t, n in sorted(info["topics"].items()))
    print(f"recover: {src} -> {info['output']}: {info['messages']} messages ({topics}) from {info['chunks']} "
          f"complete chunk(s)" + (f"; reading stopped: {info['stopped_at']}" if info["stopped_at"] else ""))
    return 0
