"""Read a YAML file with errors that name the file, line and column (one place for every config file)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from euc_ros.core.errors import ConfigError


def load_yaml(path: str | Path, what: str = "file") -> Any:
    """Return the parsed YAML of ``path``.

    Raises
    ------
    ConfigError
        ``cannot read <what>`` (missing, unreadable) or ``not valid YAML`` with the line and column.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read {what}: {exc.strerror}", path=p) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise ConfigError(f"not valid YAML: {getattr(exc, 'problem', exc)}", path=p,
                          line=None if mark is None else mark.line + 1,
                          column=None if mark is None else mark.column + 1) from None
