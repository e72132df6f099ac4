"""Reading bags: :func:`read_bag` and :class:`readable_bag`.

:func:`read_bag` iterates a bag's messages (rosbags' AnyReader), and :class:`readable_bag` gives the
checked bag directory to read for a path (a standalone ``.mcap`` file is rebuilt into a temporary bag
first).
"""
from __future__ import annotations

import tempfile
from collections.abc import Iterator
from pathlib import Path

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags.common import bag_dir, has_end_magic, listed_in_metadata, require_readable_bag
from euc_ros.core.io.bags.recovery import recover_bag
from euc_ros.core.io.msgdefs import make_typestore


class readable_bag:
    """Context manager: the bag directory to read for ``path``.

    The directory is checked (:func:`~euc_ros.core.io.bags.common.require_readable_bag`).

    A standalone ``.mcap`` file (no metadata.yaml listing it) is rebuilt into a temporary bag that
    lives until the block ends.

    Parameters
    ----------
    path : str or Path
        A bag directory, a file in one, or a standalone ``.mcap`` file.

    Raises
    ------
    InputError
        When the bag is not readable (:func:`~euc_ros.core.io.bags.common.require_readable_bag`) or the
        standalone MCAP is truncated.

    Examples
    --------
    >>> with readable_bag("ride/run_bag") as bag:   # doctest: +SKIP
    ...     reader = AnyReader([bag])
    """

    def __init__(self, path) -> None:
        self.path = Path(path)
        self._tmp = None

    def __enter__(self) -> Path:
        p = self.path
        if p.suffix.lower() == ".mcap" and p.is_file() and not listed_in_metadata(p):
            if not has_end_magic(p):
                raise InputError(f"truncated MCAP (no footer): `euc-ros recover {p}` rebuilds a bag from its "
                                 "complete chunks", path=p)
            self._tmp = tempfile.TemporaryDirectory(prefix="euc_mcap_")
            recover_bag(p, Path(self._tmp.name) / p.stem)
            return Path(self._tmp.name) / p.stem
        return require_readable_bag(p)

    def __exit__(self, *exc) -> bool:
        if self._tmp is not None:
            self._tmp.cleanup()
        return False


def _require_bag(path) -> Path:
    bag = bag_dir(path)
    if not (bag / "metadata.yaml").is_file():
        raise InputError("not a complete rosbag2 bag: no metadata.yaml (recorder killed? try recover_bag)",
                         path=bag)
    return bag


def read_bag(path, topics=None, *, raw: bool = False) -> Iterator[tuple]:
    """Iterate the messages of a bag in time order.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).
    topics : iterable of str, optional
        Only these topics (all by default).
    raw : bool
        Yield the CDR bytes instead of deserialized messages.

    Yields
    ------
    tuple
        ``(topic, msgtype, stamp_ns, msg)``: the bag's receive time [ns] and a rosbags message object
        (types auto-registered from the bag) or bytes.

    Raises
    ------
    InputError
        When the bag cannot be opened.
    """
    from rosbags.highlevel import AnyReader

    bag = _require_bag(path)
    try:
        reader = AnyReader([bag], default_typestore=make_typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own error types for unreadable bags
        raise InputError(f"cannot open bag: {exc}", path=bag) from None
    try:
        wanted = None if topics is None else set(topics)
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        for conn, stamp, data in reader.messages(connections=conns):
            yield (conn.topic, conn.msgtype, stamp, bytes(data) if raw else reader.deserialize(data, conn.msgtype))
    finally:
        reader.close()
