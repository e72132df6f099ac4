"""rosbag2 bags with MCAP storage, without rosbag2_py: write, read, check, recover, mocap series.

ROS-free (rosbags + mcap + mcap-ros2-support + numpy). The layout is rosbag2's: a directory holding
``metadata.yaml`` (version 9, as ROS 2 Jazzy writes and reads it) and one ``<name>.mcap`` file with
a ``ros2msg`` schema per type and CDR messages. The project's own types (euc_msgs) are registered
from their ``.msg`` files (:mod:`euc_ros.core.io.msgdefs`), so their RIHS01 hashes equal rclpy's.

Contents
--------
* :class:`BagWriter` - lazy connections, raw or message writes, always closes what it wrote.
* :func:`read_bag` - iterate ``(topic, msgtype, stamp_ns, msg)`` through rosbags' AnyReader.
* :func:`check_bag` - structural check (metadata.yaml as Jazzy's decoder reads it, MCAP magic,
  summary, every record of every chunk, counts, decoding with mcap-ros2-support).
* :func:`recover_bag` - rebuild a valid bag from the complete chunks of a truncated MCAP.
* :func:`inspect_bag` - what a bag holds, with the check's problems.
* :func:`read_mocap_bag`, :func:`write_mocap_bag` - :class:`~euc_ros.core.mocap.series.MocapSeries` from/to
  ``euc_msgs/msg/MocapFrame`` and/or one ``geometry_msgs/msg/PoseStamped`` per body (docs/bags.md).

Modules
-------
* :mod:`.writer` - :class:`BagWriter`.
* :mod:`.reader` - :func:`read_bag`, :class:`readable_bag`.
* :mod:`.check` - :func:`check_bag`.
* :mod:`.recovery` - :func:`recover_bag`.
* :mod:`.inspection` - :func:`inspect_bag`.
* :mod:`.mocap` - :func:`read_mocap_bag` (general route, through rosbags), :func:`write_mocap_bag`.
* :mod:`.fast_mcap` - the fast route of :func:`read_mocap_bag` (MCAP indexes, CDR decoded with numpy).
* :mod:`.posestamped` - the vectorized PoseStamped codec, per-body poses aligned into a series.
* :mod:`.common` - what they share: type names, the MCAP magic, bag paths and metadata, the MCAP scan.

See ``docs/bags.md``.
"""
from euc_ros.core.io.bags.check import JAZZY_MAX_VERSION, check_bag
from euc_ros.core.io.bags.common import MCAP_MAGIC, MOCAP_FRAME, POSE_STAMPED, RIGID_BODIES
from euc_ros.core.io.bags.inspection import inspect_bag
from euc_ros.core.io.bags.mocap import (
    CUSTOM_NAME,
    CUSTOM_RATE_HZ,
    CUSTOM_START_NS,
    STAMP_FILE_TIME,
    read_mocap_bag,
    write_mocap_bag,
)
from euc_ros.core.io.bags.posestamped import posestamped_arrays, posestamped_cdr
from euc_ros.core.io.bags.reader import read_bag, readable_bag
from euc_ros.core.io.bags.recovery import recover_bag
from euc_ros.core.io.bags.writer import DEFAULT_CHUNK_SIZE, METADATA_VERSION, ROS_DISTRO, BagWriter

__all__ = ["CUSTOM_NAME", "CUSTOM_RATE_HZ", "CUSTOM_START_NS", "DEFAULT_CHUNK_SIZE", "JAZZY_MAX_VERSION", "MCAP_MAGIC",
           "METADATA_VERSION", "MOCAP_FRAME", "POSE_STAMPED", "RIGID_BODIES", "ROS_DISTRO", "STAMP_FILE_TIME",
           "BagWriter", "check_bag", "inspect_bag", "posestamped_arrays", "posestamped_cdr", "read_bag",
           "read_mocap_bag", "readable_bag", "recover_bag", "write_mocap_bag"]
