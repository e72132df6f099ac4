"""Message definitions of the project's own interfaces (euc_msgs), for bag I/O without rclpy.

The ``.msg`` texts are read from the installed interface package (``<sys.prefix>/share/euc_msgs/msg``,
put there by our CMake build of ``msg_defs``) and, when that is absent (a checkout without the build),
from the repository's ``msg_defs/msg``. They are registered into a rosbags typestore for ROS 2 Jazzy,
so bags written here carry the same definitions and RIHS01 type hashes that rclpy publishes.

This module is ROS-free: it imports rosbags only, never rclpy or euc_msgs.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from euc_ros.core.errors import InputError

PACKAGE = "euc_msgs"

#: Repository fallback, relative to this file: euc_ros/core/io -> repository root -> msg_defs/msg.
REPO_MSG_DIR = Path(__file__).resolve().parents[3] / "msg_defs" / "msg"


def msg_dirs() -> list[Path]:
    """The directories searched for ``euc_msgs`` ``.msg`` files, in priority order.

    Returns
    -------
    list of Path
        ``<sys.prefix>/share/euc_msgs/msg`` (installed build), then the repository's ``msg_defs/msg``.
    """
    return [Path(sys.prefix) / "share" / PACKAGE / "msg", REPO_MSG_DIR]


def euc_msgs_definitions() -> dict[str, str]:
    """The ``.msg`` text of every euc_msgs message, keyed by full type name.

    Returns
    -------
    dict of str to str
        ``{'euc_msgs/msg/MocapFrame': '<text of MocapFrame.msg>', ...}`` from the first directory of
        :func:`msg_dirs` that holds any ``.msg`` file.

    Raises
    ------
    InputError
        When neither the installed package nor the repository holds the definitions.
    """
    for directory in msg_dirs():
        files = sorted(directory.glob("*.msg")) if directory.is_dir() else []
        if files:
            return {f"{PACKAGE}/msg/{p.stem}": p.read_text(encoding="utf-8") for p in files}
    raise InputError("no euc_msgs .msg definitions found (build msg_defs, or run from the repository)",
                     path=" or ".join(str(d) for d in msg_dirs()))


#: Interface packages of the mocap drivers whose messages are read from bags when their definitions are
#: installed (or in the repository's extra_interfaces/, written from their specification).
DRIVER_PACKAGES = ("mocap4r2_msgs",)
REPO_EXTRA_DIR = Path(__file__).resolve().parents[3] / "extra_interfaces"


def package_definitions(package: str) -> dict[str, str]:
    """The ``.msg`` texts of an installed interface package; empty when none holds it.

    Searched in this prefix, then AMENT_PREFIX_PATH, then the repository's extra_interfaces/.

    Parameters
    ----------
    package : str
        Interface package name, e.g. ``euc_msgs``.

    Returns
    -------
    dict of str to str
        ``.msg`` text by type name (``package/msg/Name``).
    """
    prefixes = [Path(sys.prefix)] + [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    dirs = [pre / "share" / package / "msg" for pre in prefixes] + [REPO_EXTRA_DIR / package / "msg"]
    for directory in dirs:
        files = sorted(directory.glob("*.msg")) if directory.is_dir() else []
        if files:
            return {f"{package}/msg/{f.stem}": f.read_text(encoding="utf-8") for f in files}
    return {}


def make_typestore():
    """A rosbags typestore for ROS 2 Jazzy with the euc_msgs types registered.

    Returns
    -------
    rosbags.typesys.store.Typestore
        ``get_typestore(Stores.ROS2_JAZZY)`` (std, geometry, sensor, tf2 ... messages) plus every
        message of :func:`euc_msgs_definitions`. A new object on each call: callers may register more.
    """
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict = {}
    for name, text in euc_msgs_definitions().items():
        types.update(get_types_from_msg(text, name))
    for package in DRIVER_PACKAGES:
        for name, text in package_definitions(package).items():
            types.update(get_types_from_msg(text, name))
    store.register(types)
    return store
