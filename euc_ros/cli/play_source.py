"""The bag ``euc-ros play`` replays (:class:`BagSource`).

Topic filter and start offset applied, streamed in time order (not loaded into memory).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags import readable_bag
from euc_ros.core.io.msgdefs import make_typestore


class BagSource:
    """The messages of a bag to play: topic filter and start offset applied, streamed in time order.

    Parameters
    ----------
    bag : Path
        Bag directory or its ``.mcap`` file.
    topics : list of str, optional
        Only these topics; one that the bag lacks is an error naming the bag's topics.
    start_offset : float
        Skip the first ``start_offset`` seconds of the bag [s].
    """

    def __init__(self, bag: Path, topics: list[str] | None, start_offset: float) -> None:
        from rosbags.highlevel import AnyReader

        if start_offset < 0:
            raise InputError(f"--start-offset must be >= 0, got {start_offset}", key="--start-offset")
        self.frame_topic: str | None = None
        self._bag = readable_bag(bag)
        path = self._bag.__enter__()   # left in close(): a standalone .mcap lives in a temporary bag
        self.path = path
        self.reader = AnyReader([path], default_typestore=make_typestore())
        try:
            self.reader.open()
        except Exception as exc:   # damaged beyond the checks: one line, what to do
            self._bag.__exit__(None, None, None)
            raise InputError(f"cannot read the bag ({exc}); `euc-ros inspect {bag}` lists its problems, "
                             f"`euc-ros recover {bag}` rebuilds what can be read", path=bag) from None
        have = {c.topic for c in self.reader.connections}
        requested = bool(topics)
        if topics:   # a relative name resolves in the root namespace, as ROS does: mocap/frame = /mocap/frame
            topics = [t if t in have or ("/" + t.lstrip("/")) not in have else "/" + t.lstrip("/") for t in topics]
            missing = set(topics) - have
            if missing:
                frames = [t for t in missing if t.strip("/") == "mocap/frame"]
                poses = sorted(t for t in have if t.startswith("/vrpn_mocap/") and t.endswith("/pose"))
                if frames and poses:
                    # a bag of per-body poses (vrpn_mocap, the simulator's bags): its frames are assembled
                    # from the poses as mocap_ingest would (one frame per capture stamp)
                    self.frame_topic = "/mocap/frame"
                    missing -= set(frames)
                    topics = [t for t in topics if t not in frames]
            if missing:
                self.close()
                raise InputError(f"topics not in the bag: {', '.join(sorted(missing))} "
                                 f"(bag has: {', '.join(sorted(have))})", path=path, key="--topics")
        # no --topics: every topic; else those asked for (a frame topic assembled from poses is not read)
        self.connections = [c for c in self.reader.connections if not requested or c.topic in topics]
        self.types = {c.topic: c.msgtype for c in self.connections}
        self.start_ns = self.reader.start_time + int(round(start_offset * 1e9))
        if self.frame_topic:
            self.types[self.frame_topic] = "euc_msgs/msg/MocapFrame"
            print(f"play: {bag} has no mocap/frame: frames assembled from its {len(poses)} per-body pose topics")

    def _frames(self):
        """``(stamp_ns, topic, cdr)`` of the frames assembled from the bag's per-body poses, from the start on."""
        from euc_ros.core.io.bags import read_mocap_bag
        from euc_ros.core.mocap.frame import Frame
        from euc_ros.ros.convert import frame_to_raw

        STAMP_FILE_TIME = 1   # euc_msgs/MocapFrame: capture start time plus frame / rate
        s = read_mocap_bag(self.path)
        stamps = int(s.meta.get("start_ns", 0)) + np.round(np.asarray(s.t) * 1e9).astype(np.int64)
        for k in np.flatnonzero(stamps >= self.start_ns):
            frame = Frame(int(stamps[k]), int(s.frame[k]), list(s.bodies), s.position[:, k], s.quat[:, k],
                          s.tracked[:, k], s.mean_marker_error[:, k])
            yield int(stamps[k]), self.frame_topic, frame_to_raw(frame, "world", STAMP_FILE_TIME)

    def messages(self):
        """Yield ``(stamp_ns, topic, cdr bytes)`` in time order, from the start offset on."""
        raw_messages = self._raw() if self.connections else iter(())
        if not self.frame_topic:
            yield from raw_messages
            return
        import heapq

        yield from heapq.merge(raw_messages, self._frames(), key=lambda m: m[0])

    def _raw(self):
        last = None
        for conn, stamp, raw in self.reader.messages(connections=self.connections, start=self.start_ns):
            if last is not None and stamp < last:   # never expected from rosbags; keep timing sane
                stamp = last
            last = stamp
            yield stamp, conn.topic, bytes(raw)

    def close(self) -> None:
        """Close the bag."""
        self.reader.close()
        self._bag.__exit__(None, None, None)
