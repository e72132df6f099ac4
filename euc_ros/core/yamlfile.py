"""Read a YAML file with errors that name the file, line and column (one place for every config file).

Every config file of euc_ros (session, node params, launch) goes through :func:`load_yaml`. Besides
syntax errors it refuses a key given twice in one mapping: PyYAML would silently keep the last value,
so ``wheel_radius: 0.2`` followed further down by ``wheel_radius: 0.25`` would be read as 0.25 with no
word. Keys merged in with ``<<: *anchor`` may be overridden (that is what merging is for).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from euc_ros.core.errors import ConfigError

_MERGE_TAG = "tag:yaml.org,2002:merge"


class _DuplicateKey(Exception):
    """A key given twice in one mapping (raised while walking the composed node tree)."""

    def __init__(self, key: str, mark, first_mark) -> None:
        super().__init__(key)
        self.key, self.mark, self.first_mark = key, mark, first_mark


def _key_value(loader: yaml.SafeLoader, node: yaml.Node) -> Any:
    """The Python value of a scalar key node (``1`` and ``01``, ``yes`` and ``true`` compare alike)."""
    try:
        value = loader.construct_object(node, deep=True)
        hash(value)
    except Exception:  # noqa: BLE001 - an odd key is left to the constructor to report
        return (node.tag, node.value)
    return value


def _check_unique(loader: yaml.SafeLoader, node: yaml.Node, prefix: str, seen_nodes: set[int]) -> None:
    """Walk the composed tree; raise :class:`_DuplicateKey` at the second occurrence of a key."""
    if id(node) in seen_nodes:  # an alias of a node already walked
        return
    seen_nodes.add(id(node))
    if isinstance(node, yaml.MappingNode):
        first: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if key_node.tag == _MERGE_TAG:
                continue
            name = str(key_node.value) if isinstance(key_node, yaml.ScalarNode) else "?"
            dotted = f"{prefix}.{name}" if prefix else name
            if isinstance(key_node, yaml.ScalarNode):
                k = _key_value(loader, key_node)
                if k in first:
                    raise _DuplicateKey(dotted, key_node.start_mark, first[k])
                first[k] = key_node.start_mark
            _check_unique(loader, value_node, dotted, seen_nodes)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _check_unique(loader, item, f"{prefix}[{i}]", seen_nodes)


def parse_yaml(text: str, path: str | Path | None = None) -> Any:
    """Parse one YAML document, refusing duplicate keys.

    Parameters
    ----------
    text : str
        The YAML text.
    path : str or Path, optional
        File the text came from, named in errors.

    Returns
    -------
    Any
        The document's plain Python value (None for an empty document).

    Raises
    ------
    ConfigError
        ``not valid YAML`` with the line and column, or ``key given twice`` naming the (dotted) key, the
        line and column of its second occurrence and the line of the first.
    """
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_unique(loader, node, "", set())
        return loader.construct_document(node)
    except _DuplicateKey as dup:
        raise ConfigError(f"key given twice (first at line {dup.first_mark.line + 1}); keep one", path=path,
                          line=dup.mark.line + 1, column=dup.mark.column + 1, key=dup.key) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise ConfigError(f"not valid YAML: {getattr(exc, 'problem', exc)}", path=path,
                          line=None if mark is None else mark.line + 1,
                          column=None if mark is None else mark.column + 1) from None
    finally:
        loader.dispose()


def load_yaml(path: str | Path, what: str = "file") -> Any:
    """The parsed YAML of ``path``.

    Parameters
    ----------
    path : str or Path
        The YAML file.
    what : str
        What the file is, named in the error when it cannot be read.

    Returns
    -------
    Any
        The document's plain Python value (None for an empty document).

    Raises
    ------
    ConfigError
        ``cannot read <what>`` (missing, unreadable), ``not valid YAML`` with the line and column, or a
        key given twice in one mapping (its line, column and dotted name).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read {what}: {exc.strerror}", path=p) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"cannot read {what}: not UTF-8 text (byte {exc.start})", path=p) from None
    return parse_yaml(text, p)
