"""Inspection, :func:`inspect_bag`.

What a bag holds (topics, types, counts, rates, time span, storage) with the problems of the structural
check.
"""
from __future__ import annotations

import yaml

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags.check import check_bag
from euc_ros.core.io.bags.common import bag_dir, scan_mcap


def inspect_bag(path) -> dict:
    """Describe a bag: topics, types, counts, time span, storage, and the problems of :func:`check_bag`.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).

    Returns
    -------
    dict
        ``path``, ``storage``, ``metadata_version``, ``ros_distro``, ``files`` [{name, bytes}],
        ``topics`` [{name, type, count, rate_hz}], ``message_count``, ``start_ns``, ``end_ns``,
        ``duration_s``, ``problems`` (list of str; empty when the bag is sound). For a bag without
        metadata.yaml the figures come from what the MCAP scan could read. A topic's ``rate_hz`` is
        ``(count - 1)`` over the span from its own first to its last message (log time), None with
        fewer than two messages; ``duration_s`` is the bag's span over all topics.

    Raises
    ------
    InputError
        When the bag directory does not exist.
    """
    bag = bag_dir(path)
    if not bag.is_dir():
        raise InputError("no such bag directory", path=bag)
    problems = check_bag(bag)
    info = None
    meta_file = bag / "metadata.yaml"
    if meta_file.is_file():
        try:
            info = (yaml.safe_load(meta_file.read_text(encoding="utf-8")) or {}).get("rosbag2_bagfile_information")
        except (yaml.YAMLError, AttributeError):
            info = None
    files = sorted(bag.glob("*.mcap"))
    out = {"path": str(bag), "storage": "mcap", "metadata_version": None, "ros_distro": None,
           "files": [{"name": f.name, "bytes": f.stat().st_size} for f in files], "topics": [],
           "message_count": 0, "start_ns": None, "end_ns": None, "duration_s": 0.0, "problems": problems}
    topics: dict[str, dict] = {}
    spans: dict[str, tuple[int, int]] = {}      # topic -> (first, last) log time [ns]
    first = last = None
    for file in files:
        scan, _ = scan_mcap(file, validate_crcs=False)
        for cid, ch in scan.channels.items():
            schema = scan.schemas.get(ch.schema_id)
            entry = topics.setdefault(ch.topic, {"name": ch.topic, "type": schema.name if schema else "?",
                                                 "count": 0})
            entry["count"] += scan.counts.get(cid, 0)
            if cid in scan.span_ns:
                lo, hi = scan.span_ns[cid]
                seen = spans.get(ch.topic)
                spans[ch.topic] = (lo, hi) if seen is None else (min(seen[0], lo), max(seen[1], hi))
        if scan.first_ns is not None:
            first = scan.first_ns if first is None else min(first, scan.first_ns)
            last = scan.last_ns if last is None else max(last, scan.last_ns)
    if isinstance(info, dict):
        out["storage"] = info.get("storage_identifier", "mcap")
        out["metadata_version"] = info.get("version")
        out["ros_distro"] = info.get("ros_distro")
    duration = (last - first) * 1e-9 if first is not None else 0.0
    for entry in topics.values():      # each topic over its own span: topics start and end at different times
        lo, hi = spans.get(entry["name"], (0, 0))
        entry["rate_hz"] = (entry["count"] - 1) / ((hi - lo) * 1e-9) if hi > lo and entry["count"] > 1 else None
    out.update(topics=sorted(topics.values(), key=lambda e: e["name"]),
               message_count=sum(e["count"] for e in topics.values()), start_ns=first, end_ns=last,
               duration_s=duration)
    return out
