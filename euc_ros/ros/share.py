"""Where the package's shared files (``launch/``, ``config/``) are: ``$(find-pkg-share euc_ros)``."""
from __future__ import annotations

import os
from pathlib import Path

from euc_ros.core.errors import ConfigError

#: The ROS package name.
PACKAGE = "euc_ros"


def package_share() -> Path:
    """The directory ``$(find-pkg-share euc_ros)`` stands for: the one holding ``launch/`` and ``config/``.

    The share directory of the install this module comes from (``<prefix>/share/euc_ros`` of a colcon
    install or a wheel), else the source checkout it comes from (an editable install: the repository
    root), else the first ``AMENT_PREFIX_PATH`` entry that indexes the package.

    Raises
    ------
    ConfigError
        When none of these holds ``launch/`` and ``config/``.
    """
    package = Path(__file__).resolve().parents[1]            # .../euc_ros
    candidates = []
    if package.parent.name in ("site-packages", "dist-packages"):
        candidates.append(package.parents[3] / "share" / PACKAGE)
    else:
        candidates.append(package.parent)
    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        if (Path(prefix) / "share" / "ament_index" / "resource_index" / "packages" / PACKAGE).exists():
            candidates.append(Path(prefix) / "share" / PACKAGE)
    for candidate in candidates:
        if (candidate / "launch").is_dir() and (candidate / "config").is_dir():
            return candidate
    raise ConfigError(f"cannot find the {PACKAGE} share directory (with launch/ and config/) in "
                      f"{', '.join(map(str, candidates))}: install the package (pip install -e . or colcon "
                      "build) or source its install space")
