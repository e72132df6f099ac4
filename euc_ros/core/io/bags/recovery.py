"""Recovery, :func:`recover_bag`.

A valid bag rebuilt from the complete chunks of a truncated MCAP file (a recorder killed before it closed
the bag).
"""
from __future__ import annotations

from pathlib import Path

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags.common import MCAP_MAGIC, bag_dir, scan_mcap
from euc_ros.core.io.bags.writer import BagWriter


def recover_bag(path, out=None) -> dict:
    """Rebuild a valid bag from what can be read of a truncated MCAP (messages in complete chunks).

    Parameters
    ----------
    path : str or Path
        Damaged bag directory (or its .mcap file), e.g. from a recorder killed with SIGKILL.
    out : str or Path, optional
        New bag directory; default ``<bag>_recovered`` next to the input.

    Returns
    -------
    dict
        ``output`` (Path), ``messages`` recovered, ``topics`` {topic: count}, ``chunks`` complete
        chunks read, ``stopped_at`` (why reading stopped, None if the file was complete).

    Raises
    ------
    InputError
        No MCAP file, or not a single complete message to recover.
    """
    bag = bag_dir(path)
    mcaps = [Path(path)] if Path(path).suffix == ".mcap" else sorted(bag.glob("*.mcap"))
    if not mcaps:
        raise InputError("no .mcap file to recover", path=bag)
    dest = Path(out) if out is not None else bag.with_name(bag.name + "_recovered")
    total, topics, chunks, stopped = 0, {}, 0, None
    scans = []
    for file in mcaps:
        with open(file, "rb") as f:
            if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                raise InputError("not an MCAP file (no magic)", path=file)
        scan, messages = scan_mcap(file, keep_messages=True, validate_crcs=False)
        scans.append((scan, messages))
        chunks += scan.n_chunks
        stopped = stopped or scan.error
    if not any(messages for _, messages in scans):
        raise InputError(f"nothing to recover: no complete chunk ({stopped or 'empty file'})", path=bag)
    with BagWriter(dest) as writer:
        for scan, messages in scans:
            for cid, stamp, data in sorted(messages, key=lambda m: m[1]):
                ch = scan.channels.get(cid)
                schema = scan.schemas.get(ch.schema_id) if ch is not None else None
                if schema is None:
                    continue
                msgdef = schema.data.decode("utf-8")
                writer.connection(ch.topic, schema.name, msgdef=msgdef)
                writer.write_raw(ch.topic, schema.name, data, stamp)
                total += 1
                topics[ch.topic] = topics.get(ch.topic, 0) + 1
    return {"output": dest, "messages": total, "topics": topics, "chunks": chunks, "stopped_at": stopped}
