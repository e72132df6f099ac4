"""Where the ``mocap_ingest`` node's frames come from: one class per source, one small interface.

===========================  =========================================  ==========================================
``source`` (``topic_type``)  class                                      frames from
===========================  =========================================  ==========================================
``csv``                      :class:`.csv_replay.CsvReplay`             a Motive CSV export, replayed on a timer
``topics`` (pose_stamped)    :class:`.pose_topics.PoseTopics`           one PoseStamped per body (vrpn_mocap)
``topics`` (rigid_bodies)    :class:`.pose_topics.RigidBodiesTopic`     mocap4r2_msgs/RigidBodies, one per frame
``natnet``                   :class:`.natnet.NatNetSource`              Motive over NatNet (UDP)
===========================  =========================================  ==========================================

Each is a :class:`~euc_ros.ros.mocap_sources.base.MocapSource`; :func:`make_source` picks one from the
node's parameters.
"""
from __future__ import annotations

import importlib

from euc_ros.core.errors import ConfigError
from euc_ros.core.session import load_session
from euc_ros.ros.mocap_sources.base import MocapSource

#: Source class by (``source``, ``topic_type``) parameter values; imported when chosen.
SOURCES = {
    ("csv", None): "euc_ros.ros.mocap_sources.csv_replay:CsvReplay",
    ("topics", "pose_stamped"): "euc_ros.ros.mocap_sources.pose_topics:PoseTopics",
    ("topics", "rigid_bodies"): "euc_ros.ros.mocap_sources.pose_topics:RigidBodiesTopic",
    ("natnet", None): "euc_ros.ros.mocap_sources.natnet:NatNetSource",
}


def make_source(node, config: dict) -> MocapSource:
    """The source the ``source`` (and ``topic_type``) parameters of ``config`` choose, not set up yet."""
    kind = config["source"]
    path = SOURCES[(kind, config["topic_type"] if kind == "topics" else None)]
    module, cls = path.split(":")
    return getattr(importlib.import_module(module), cls)(node, config)


def up_axis_config(session_file: str, world_up: str):
    """(session or None, the up axis to convert with) from the parameters.

    The session is the one source of ``world_up``; a ``world_up`` parameter that contradicts it is a
    ConfigError naming both.
    """
    session = load_session(session_file) if session_file else None
    if session is None:
        return None, world_up or "y"
    if world_up and world_up != session.world_up:
        raise ConfigError(f"world_up {world_up!r} contradicts the session's world_up {session.world_up!r} "
                          f"({session_file}): leave world_up empty, the session gives it",
                          key="mocap_ingest.ros__parameters.world_up")
    return session, session.world_up


__all__ = ["MocapSource", "SOURCES", "make_source", "up_axis_config"]
