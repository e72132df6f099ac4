"""Open a recording of any supported kind as a :class:`~euc_ros.core.mocap.series.MocapSeries` (Z-up, metres).

* ``*.csv``: a Motive CSV export (docs/motive_csv.md), read with
  :func:`euc_ros.core.io.motive_csv.read_motive_csv` in the Motive world given by ``world_up``;
* a directory holding ``metadata.yaml`` or ``*.mcap`` files, or an ``.mcap`` file: a rosbag2 bag
  (docs/bags.md, always Z-up), read with :func:`euc_ros.core.io.bags.read_mocap_bag`.

The readers are imported only when needed.
"""
from __future__ import annotations

from pathlib import Path

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags import read_mocap_bag
from euc_ros.core.mocap.series import MocapSeries


def recording_kind(path: str | Path) -> str:
    """``"csv"`` or ``"bag"`` for ``path``; InputError naming the path otherwise.

    Parameters
    ----------
    path : str or Path
        A Motive CSV, a bag directory or an ``.mcap`` file.

    Returns
    -------
    str
        ``"csv"`` or ``"bag"``.

    Raises
    ------
    InputError
        When the path does not exist or is no recording.
    """
    p = Path(path)
    if not p.exists():
        raise InputError("no such file or directory", path=p)
    if p.is_dir():
        if (p / "metadata.yaml").is_file() or any(p.glob("*.mcap")):
            return "bag"
        raise InputError("directory is not a rosbag2 bag (no metadata.yaml or .mcap file)", path=p)
    suffix = p.suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix == ".mcap":
        return "bag"
    raise InputError("unknown recording type (expected a Motive .csv, a bag directory or an .mcap file)", path=p)


def load_recording(path: str | Path, world_up: str = "y", *, bodies: list[str] | None = None) -> MocapSeries:
    """Read a Motive CSV or a bag into a Z-up :class:`~euc_ros.core.mocap.series.MocapSeries`.

    Parameters
    ----------
    path : str or Path
        ``.csv`` file, bag directory or ``.mcap`` file.
    world_up : {"y", "z"}
        Up axis of the Motive world of a CSV (the session's ``world_up``); bags are always Z-up.
    bodies : list of str, optional
        Rigid bodies to return, in this order (default: all).

    Returns
    -------
    MocapSeries
        With ``meta["path"]`` set to ``path``.

    Raises
    ------
    InputError
        A CSV with no rigid body (markers or skeleton bones only), naming what it holds.
    """
    kind = recording_kind(path)
    if kind == "csv":
        from euc_ros.core.io.motive_csv import read_motive_csv, require_rigid_bodies

        series = read_motive_csv(path, world_up=world_up, bodies=bodies)
        require_rigid_bodies(series, path)
    else:
        series = read_mocap_bag(path, bodies=bodies)
    series.meta.setdefault("path", str(path))
    if not series.name:
        series.name = Path(path).stem
    return series
