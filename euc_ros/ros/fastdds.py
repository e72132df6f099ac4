"""Fast DDS transport profiles a process runs with: the recorder's deep shared-memory port, a fast publisher's segment.

A shared-memory message that finds its receiver's Fast DDS port full is dropped, and the default
port queues 512 descriptors (5 ms at 100k msgs/s). The ``recorder`` console script therefore runs
with :data:`RECORDER_PROFILE` (a 65536-descriptor port) unless the Fast DDS transports were chosen
already (:data:`TRANSPORT_CHOICES`, a ``DEFAULT_FASTRTPS_PROFILES.xml`` in the working directory) or
the RMW is not Fast DDS. A publisher's own segment bounds how many of its messages can wait for any
receiver (512 by default): above ~50k msgs/s from one process, give it :data:`FAST_PUBLISHER_PROFILE`.
"""
from __future__ import annotations

from pathlib import Path

_DATA = Path(__file__).resolve().parent.parent / "data"
#: Fast DDS participant profile the ``recorder`` console script runs with (a deep shared-memory port).
RECORDER_PROFILE = _DATA / "fastdds_recorder.xml"
#: Fast DDS participant profile for a process publishing faster than ~50k msgs/s (a 64 MiB segment).
FAST_PUBLISHER_PROFILE = _DATA / "fastdds_fast_publisher.xml"
#: Environment variables by which Fast DDS 2.14 transports are chosen already: the recorder keeps them.
TRANSPORT_CHOICES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE", "FASTDDS_BUILTIN_TRANSPORTS")


def uses_fast_dds(env) -> bool:
    """Whether ``env`` selects Fast DDS (``RMW_IMPLEMENTATION`` unset is Jazzy's default, Fast DDS)."""
    return (env.get("RMW_IMPLEMENTATION", "") or "rmw_fastrtps_cpp").startswith("rmw_fastrtps")


def transport_env(env, cwd=".", profile: Path = RECORDER_PROFILE) -> dict:
    """The variables to add to ``env`` so that Fast DDS uses ``profile``.

    ``{}`` when the transports are chosen already (see :data:`TRANSPORT_CHOICES`; Fast DDS also reads
    ``DEFAULT_FASTRTPS_PROFILES.xml`` from the working directory) or the RMW is not Fast DDS.
    """
    if not uses_fast_dds(env) or any(env.get(k) for k in TRANSPORT_CHOICES) \
            or (Path(cwd) / "DEFAULT_FASTRTPS_PROFILES.xml").exists():
        return {}
    if not profile.is_file():
        raise FileNotFoundError(f"Fast DDS profile {profile} is missing (euc_ros/data is part of the package)")
    return {"FASTRTPS_DEFAULT_PROFILES_FILE": str(profile)}
