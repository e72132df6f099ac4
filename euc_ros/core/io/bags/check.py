"""The structural check of a bag, :func:`check_bag`.

It checks metadata.yaml as ROS 2 Jazzy's decoder reads it, then every listed MCAP file (magic, footer,
summary, every record of every chunk, counts against the statistics and metadata.yaml, decoding with
mcap-ros2-support).
"""
from __future__ import annotations

from pathlib import Path

import yaml

from euc_ros.core.io.bags.common import MCAP_MAGIC, McapScan, bag_dir, scan_mcap

#: Newest metadata version ROS 2 Jazzy decodes.
JAZZY_MAX_VERSION = 9


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_scalar(v) -> bool:
    """yaml-cpp ``as<std::string>()`` accepts any scalar (not null, not a sequence or map)."""
    return isinstance(v, (str, int, float, bool)) and v is not None


_QOS_KEYS = ("history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
             "liveliness_lease_duration", "avoid_ros_namespace_conventions")


class _Meta:
    """Walk metadata.yaml the way rosbag2 Jazzy's YAML decoder does, collecting problems."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems

    def get(self, node, key: str, where: str, kind: str):
        path = f"{where}.{key}" if where else key
        if not isinstance(node, dict) or key not in node:
            self.problems.append(f"metadata.yaml: missing key '{path}'")
            return None
        v = node[key]
        ok = {"int": _is_int(v), "uint": _is_int(v) and v >= 0, "scalar": _is_scalar(v),
              "seq": isinstance(v, list), "map": isinstance(v, dict),
              "map_or_null": v is None or isinstance(v, dict)}[kind]
        if not ok:
            want = {"int": "an integer", "uint": "a non-negative integer", "scalar": "a string",
                    "seq": "a list", "map": "a mapping", "map_or_null": "a mapping"}[kind]
            self.problems.append(f"metadata.yaml: '{path}' must be {want}, got {type(v).__name__} {v!r:.60}")
            return None
        return v

    def nanoseconds(self, node, key: str, where: str, field: str):
        sub = self.get(node, key, where, "map")
        return None if sub is None else self.get(sub, field, f"{where}.{key}" if where else key, "uint")


#: rosbag2 Jazzy's QoS policy words (rosbag2_storage/qos.cpp decodes these, or their rmw numbers).
_QOS_POLICIES = {
    "history": ("system_default", "keep_last", "keep_all", "unknown"),
    "reliability": ("system_default", "reliable", "best_effort", "unknown", "best_available"),
    "durability": ("system_default", "transient_local", "volatile", "unknown", "best_available"),
    "liveliness": ("system_default", "automatic", "manual_by_node", "manual_by_topic", "unknown", "best_available"),
}


def _check_qos(q: dict, where: str, problems: list[str]) -> None:
    """One ``offered_qos_profiles`` entry as the Jazzy decoder reads it.

    Each policy is a word or a number, the depth an int, the durations {sec, nsec}, and
    ``avoid_ros_namespace_conventions`` a bool.
    """
    for key, words in _QOS_POLICIES.items():
        v = q.get(key)
        if v is not None and not (_is_int(v) or v in words):
            problems.append(f"metadata.yaml: '{where}.{key}' is {v!r}, not one of {', '.join(words)}")
    if "depth" in q and not _is_int(q["depth"]):
        problems.append(f"metadata.yaml: '{where}.depth' must be an integer")
    for key in ("deadline", "lifespan", "liveliness_lease_duration"):
        v = q.get(key)
        if v is not None and not (isinstance(v, dict) and all(_is_int(v.get(f)) and v.get(f) >= 0
                                                                  for f in ("sec", "nsec"))):
            problems.append(f"metadata.yaml: '{where}.{key}' must be {{sec, nsec}} (unsigned integers)")
    v = q.get("avoid_ros_namespace_conventions")
    if v is not None and not isinstance(v, bool):
        problems.append(f"metadata.yaml: '{where}.avoid_ros_namespace_conventions' must be true or false")


def _check_metadata(bag: Path, problems: list[str]) -> dict | None:
    """Validate metadata.yaml; return the information block (or None when unusable)."""
    meta_file = bag / "metadata.yaml"
    if not meta_file.is_file():
        problems.append("metadata.yaml missing: the bag was not closed (recorder killed?); "
                        "recover_bag can rebuild it from the complete chunks")
        return None
    try:
        doc = yaml.safe_load(meta_file.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        problems.append(f"metadata.yaml: not valid YAML: {exc}")
        return None
    m = _Meta(problems)
    info = m.get(doc, "rosbag2_bagfile_information", "", "map")
    if info is None:
        return None
    w = "rosbag2_bagfile_information"
    version = m.get(info, "version", w, "int")
    if version is None:
        return None
    if version > JAZZY_MAX_VERSION:
        problems.append(f"metadata.yaml: version {version} is newer than ROS 2 Jazzy reads ({JAZZY_MAX_VERSION})")
    storage = m.get(info, "storage_identifier", w, "scalar")
    if storage is not None and storage != "mcap":
        problems.append(f"metadata.yaml: storage_identifier is {storage!r}, expected 'mcap'")
    m.nanoseconds(info, "duration", w, "nanoseconds")
    m.nanoseconds(info, "starting_time", w, "nanoseconds_since_epoch")
    m.get(info, "message_count", w, "uint")
    topics = m.get(info, "topics_with_message_count", w, "seq") or []
    for i, t in enumerate(topics):
        tw = f"{w}.topics_with_message_count[{i}]"
        tm = m.get(t, "topic_metadata", tw, "map")
        m.get(t, "message_count", tw, "uint")
        if tm is None:
            continue
        tmw = f"{tw}.topic_metadata"
        for key in ("name", "type", "serialization_format"):
            m.get(tm, key, tmw, "scalar")
        if version >= 9:
            profiles = m.get(tm, "offered_qos_profiles", tmw, "seq") or []
            for k, q in enumerate(profiles):
                if not isinstance(q, dict):
                    problems.append(f"metadata.yaml: '{tmw}.offered_qos_profiles[{k}]' must be a mapping")
                    continue
                missing = [key for key in _QOS_KEYS if key not in q]
                if missing:
                    problems.append(f"metadata.yaml: '{tmw}.offered_qos_profiles[{k}]' lacks {', '.join(missing)}")
                _check_qos(q, f"{tmw}.offered_qos_profiles[{k}]", problems)
        elif version >= 4:
            m.get(tm, "offered_qos_profiles", tmw, "scalar")
        if version >= 7:
            m.get(tm, "type_description_hash", tmw, "scalar")
    paths = m.get(info, "relative_file_paths", w, "seq") or []
    for k, p in enumerate(paths):
        if not _is_scalar(p):
            problems.append(f"metadata.yaml: '{w}.relative_file_paths[{k}]' must be a string")
    if version >= 3:
        m.get(info, "compression_format", w, "scalar")
        m.get(info, "compression_mode", w, "scalar")
    if version >= 5:
        files = m.get(info, "files", w, "seq") or []
        for k, f in enumerate(files):
            fw = f"{w}.files[{k}]"
            m.get(f, "path", fw, "scalar")
            m.nanoseconds(f, "starting_time", fw, "nanoseconds_since_epoch")
            m.nanoseconds(f, "duration", fw, "nanoseconds")
            m.get(f, "message_count", fw, "uint")
    if version >= 6:
        custom = m.get(info, "custom_data", w, "map_or_null")
        for k, v in (custom or {}).items():
            if not (_is_scalar(k) and _is_scalar(v)):
                problems.append(f"metadata.yaml: custom_data entry {k!r}: {v!r} is not string: string")
    if version >= 8:
        m.get(info, "ros_distro", w, "scalar")
    # Internal consistency.
    counts = [t.get("message_count") for t in topics if isinstance(t, dict)]
    total = info.get("message_count")
    if _is_int(total) and all(_is_int(c) for c in counts) and sum(counts) != total:
        problems.append(f"metadata.yaml: topic message counts sum to {sum(counts)}, message_count is {total}")
    return info


def _check_mcap(file: Path, info: dict | None, problems: list[str]) -> McapScan | None:
    size = file.stat().st_size
    with open(file, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
        f.seek(max(0, size - len(MCAP_MAGIC)))
        tail = f.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        problems.append(f"{file.name}: no MCAP magic at the start: not an MCAP file")
        return None
    scan, _ = scan_mcap(file)
    truncated = tail != MCAP_MAGIC or not scan.footer
    if truncated:
        problems.append(f"{file.name}: truncated ({size} bytes, no footer/end magic): the recorder was killed "
                        f"before closing; {scan.n_messages} messages in {scan.n_chunks} complete chunks are "
                        f"recoverable with recover_bag")
        return scan
    if scan.error:
        problems.append(f"{file.name}: record parse failed: {scan.error}")
        return scan
    from mcap.reader import make_reader

    try:
        with open(file, "rb") as f:
            summary = make_reader(f).get_summary()
    except Exception as exc:  # damaged summary section
        summary = None
        problems.append(f"{file.name}: summary section unreadable: {exc}")
    if summary is None:
        problems.append(f"{file.name}: no summary section")
    elif summary.statistics is None:
        problems.append(f"{file.name}: summary has no statistics record")
    else:
        st = summary.statistics
        if st.message_count != scan.n_messages:
            problems.append(f"{file.name}: statistics say {st.message_count} messages, records hold {scan.n_messages}")
        # a channel registered (a subscription matched) but never written is counted 0 by the writer
        # and has no message records: that is a legal, complete bag
        stated = {k: v for k, v in st.channel_message_counts.items() if v}
        if stated != {k: v for k, v in scan.counts.items() if v}:
            problems.append(f"{file.name}: per-channel statistics {dict(st.channel_message_counts)} disagree with "
                            f"the records {scan.counts}")
        if st.chunk_count != scan.n_chunks or len(summary.chunk_indexes) != scan.n_chunks:
            problems.append(f"{file.name}: {scan.n_chunks} chunks in the data, statistics say {st.chunk_count}, "
                            f"{len(summary.chunk_indexes)} chunk indexes")
    if info is not None:
        by_topic: dict[str, int] = {}
        types: dict[str, str] = {}
        for cid, ch in scan.channels.items():
            by_topic[ch.topic] = by_topic.get(ch.topic, 0) + scan.counts.get(cid, 0)
            schema = scan.schemas.get(ch.schema_id)
            types[ch.topic] = schema.name if schema is not None else "?"
        meta_topics = {}
        for t in info.get("topics_with_message_count") or []:
            tm = t.get("topic_metadata") if isinstance(t, dict) else None
            if isinstance(tm, dict) and "name" in tm:
                meta_topics[tm["name"]] = (tm.get("type"), t.get("message_count"))
        for topic, (mtype, count) in meta_topics.items():
            if topic not in by_topic:
                problems.append(f"metadata.yaml lists topic {topic} which has no channel in {file.name}")
                continue
            if count != by_topic[topic]:
                problems.append(f"message count of {topic}: metadata.yaml says {count}, {file.name} holds "
                                f"{by_topic[topic]}")
            if mtype != types[topic]:
                problems.append(f"type of {topic}: metadata.yaml says {mtype}, {file.name} schema is {types[topic]}")
        for topic in sorted(set(by_topic) - set(meta_topics)):
            problems.append(f"topic {topic} is in {file.name} but not in metadata.yaml")
        if _is_int(info.get("message_count")) and info["message_count"] != scan.n_messages:
            problems.append(f"message_count: metadata.yaml says {info['message_count']}, {file.name} holds "
                            f"{scan.n_messages}")
    # Decode everything with the independent ROS 2 reader of the mcap project.
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    try:
        with open(file, "rb") as f:
            n = sum(1 for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
        if n != scan.n_messages:
            problems.append(f"{file.name}: mcap-ros2-support decoded {n} of {scan.n_messages} messages")
    except Exception as exc:  # any decoder failure is a finding, not a crash
        problems.append(f"{file.name}: mcap-ros2-support cannot decode: {type(exc).__name__}: {exc}")
    return scan


def check_bag(path) -> list[str]:
    """Check a bag's structure; return the problems found (empty list: OK).

    Checks, in order: metadata.yaml keys and YAML types as ROS 2 Jazzy's decoder reads them
    (``rosbag2_storage/yaml.hpp``, metadata version 9: ``offered_qos_profiles`` is a list), the
    internal consistency of its counts; for each listed file: MCAP magic at start and end, the footer
    and summary (statistics, chunk indexes), every record of every chunk parses (CRCs validated when
    present), per-channel counts agree with the statistics and with metadata.yaml, topic types agree,
    and every message decodes with mcap-ros2-support. A truncated file (recorder killed: no
    summary, no footer) is reported as such with the number of recoverable messages.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).

    Returns
    -------
    list of str
        One line per problem.
    """
    bag = bag_dir(path)
    if not bag.is_dir():
        return [f"{bag}: no such bag directory"]
    problems: list[str] = []
    info = _check_metadata(bag, problems)
    if info is not None and isinstance(info.get("relative_file_paths"), list):
        files = [bag / str(p) for p in info["relative_file_paths"]]
    else:
        files = sorted(bag.glob("*.mcap"))
    if not files:
        problems.append("no .mcap file in the bag")
    for file in files:
        if not file.is_file():
            problems.append(f"{file.name}: listed in metadata.yaml but missing")
            continue
        _check_mcap(file, info if len(files) == 1 else None, problems)
    return problems
