"""Declared parameters from one table per node (the generate_parameter_library idea, in a few lines).

Each node lists ``ParamSpec`` entries; :func:`declare_params` declares them with a description,
type, unit and range, reads the values (from ``--params-file`` or overrides), validates them and
returns a plain dict. Invalid values raise :class:`ConfigError` naming the parameter.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from euc_ros.core.errors import ConfigError
from euc_ros.core.session import Session, load_session
from euc_ros.core.yamlfile import load_yaml


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter: name, default, description, unit, optional range or choices."""

    name: str
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] | None = None
    #: ``ros2 param set`` takes effect while the node runs (the node reacts); otherwise a set is refused
    #: with the reason (the value is read at start-up)
    live: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """Return the ROS parameter descriptor (description, unit, range, read-only)."""
        text = self.description + (f" [{self.unit}]" if self.unit else "")
        if self.choices:
            text += f" (one of: {', '.join(self.choices)})"
        text += "; settable while running" if self.live else "; read at start-up (a set is refused: restart)"
        # not read_only: rcl would refuse a set before our callback could say why (watch_params)
        d = ParameterDescriptor(description=text, read_only=False)
        # a string with choices such as y/n: the ROS command line and YAML 1.1 read a bare y as true;
        # accept the bool and map it back (yaml_bool_to_choice) instead of refusing the natural spelling
        d.dynamic_typing = bool(self.choices) and isinstance(self.default, str)
        if self.low is not None and self.high is not None:
            if isinstance(self.default, bool):
                pass
            elif isinstance(self.default, int):
                d.integer_range = [IntegerRange(from_value=int(self.low), to_value=int(self.high), step=0)]
            elif isinstance(self.default, float):
                d.floating_point_range = [FloatingPointRange(from_value=float(self.low), to_value=float(self.high),
                                                             step=0.0)]
        return d


def _param_type(default: Any) -> Parameter.Type:
    if isinstance(default, bool):
        return Parameter.Type.BOOL
    if isinstance(default, int):
        return Parameter.Type.INTEGER
    if isinstance(default, float):
        return Parameter.Type.DOUBLE
    if isinstance(default, str):
        return Parameter.Type.STRING
    if isinstance(default, (list, tuple)):
        if all(isinstance(v, str) for v in default):
            return Parameter.Type.STRING_ARRAY
        if all(isinstance(v, bool) for v in default) and default:
            return Parameter.Type.BOOL_ARRAY
        if all(isinstance(v, int) and not isinstance(v, bool) for v in default) and default:
            return Parameter.Type.INTEGER_ARRAY
        return Parameter.Type.DOUBLE_ARRAY
    raise TypeError(f"unsupported parameter default {default!r}")


_YAML_TRUE = ("y", "yes", "on", "true")
_YAML_FALSE = ("n", "no", "off", "false")


def yaml_bool_to_choice(value, choices) -> Any:
    """Map a bool that YAML 1.1 made of a bare ``y``/``n``/``yes``/``on``... back to the choice it spelt.

    >>> yaml_bool_to_choice(True, ("y", "z")), yaml_bool_to_choice("z", ("y", "z"))
    ('y', 'z')
    """
    if isinstance(value, bool) and choices:
        for word in (_YAML_TRUE if value else _YAML_FALSE):
            if word in choices:
                return word
    return value


def declare_params(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """Declare every spec on ``node`` and return validated values by name.

    Raises
    ------
    ConfigError
        A value outside its range or choices, or of the wrong type, naming the parameter.
    """
    values: dict[str, Any] = {}
    for spec in specs:
        ptype = _param_type(spec.default)
        try:
            param = node.declare_parameter(spec.name, spec.default if spec.default != [] else ptype,
                                           spec.descriptor())
        except Exception as exc:  # rclpy raises several types for bad overrides
            raise ConfigError(f"invalid value: {exc}", key=f"{node.get_name()}.ros__parameters.{spec.name}") from None
        try:
            value = check_value(spec, param.value)
        except ValueError as exc:
            raise ConfigError(str(exc), key=f"{node.get_name()}.ros__parameters.{spec.name}") from None
        if spec.choices and isinstance(spec.default, str) and value != param.value:
            node.set_parameters([Parameter(spec.name, value=value)])
        values[spec.name] = value
    watch_params(node, specs, values, getattr(node, "on_parameter", None))
    return values


def required_session(node_name: str, config: dict[str, Any]) -> tuple[Session, str]:
    """Load the session of a node's required ``session_file`` parameter.

    Parameters
    ----------
    node_name : str
        The node's name, for the key of the error.
    config : dict
        The node's parameters (:func:`declare_params`).

    Returns
    -------
    session : Session
    hardware_id : str
        ``session:<file name>``: what the node's diagnostics concern (the rider and EUC of the session).

    Raises
    ------
    ConfigError
        ``session_file`` is empty (key ``<node_name>.ros__parameters.session_file``), or the file is not
        a valid session.
    """
    if not config["session_file"]:
        raise ConfigError("parameter 'session_file' is required", key=f"{node_name}.ros__parameters.session_file")
    return load_session(config["session_file"]), f"session:{Path(config['session_file']).name}"


def check_value(spec: ParamSpec, value: Any) -> Any:
    """The value of ``spec`` as the node uses it, or ValueError saying what is accepted.

    A choice spelt by YAML as a bool is mapped back, an int becomes a float for a double; the ValueError comes
    when the value is outside the choices or range.
    """
    if isinstance(value, tuple):
        value = list(value)
    if spec.choices and isinstance(spec.default, str):
        value = yaml_bool_to_choice(value, spec.choices)
    if isinstance(spec.default, float) and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if spec.choices and value not in spec.choices:
        hint = " (a bare y/n/yes/no/on/off is read as a boolean)" if isinstance(value, bool) else ""
        raise ValueError(f"must be one of {', '.join(spec.choices)}, got {value!r}{hint}")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
            raise ValueError(f"must be in [{spec.low}, {spec.high}], got {value!r}")
    return value


def watch_params(node: Node, specs: Sequence[ParamSpec], config: dict[str, Any], apply=None) -> None:
    """React to ``ros2 param set`` (the parameter services).

    A ``live`` parameter is checked against its declaration, stored in ``config`` and passed to
    ``apply(name, value)`` (which may raise ConfigError or ValueError to refuse); any other is refused with
    the reason. rcl has already checked the type.
    """
    from rcl_interfaces.msg import SetParametersResult

    by_name = {s.name: s for s in specs}

    def on_set(params) -> SetParametersResult:
        checked = []
        for p in params:
            spec = by_name.get(p.name)
            if spec is None:
                continue   # use_sim_time and the like: rclpy's own
            if not spec.live:
                return SetParametersResult(successful=False, reason=(
                    f"'{p.name}' is read at start-up: restart {node.get_name()} with -p {p.name}:=VALUE "
                    "(or set it in its params file)"))
            try:
                checked.append((p.name, check_value(spec, p.value)))
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=f"'{p.name}' {exc}")
        for name, value in checked:
            try:
                if apply is not None:
                    apply(name, value)
            except (ConfigError, ValueError) as exc:
                return SetParametersResult(successful=False, reason=f"'{name}': {exc}")
            config[name] = value
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)


def validate_params_file(path: str, node_name: str, specs: Sequence[ParamSpec]) -> None:
    """Check a ``--params-file`` YAML before rcl parses it, so errors name the file and key.

    Accepts the ROS 2 layout ``{node_name or /** : {ros__parameters: {...}}}``; keys of other nodes
    are ignored (one file may configure several nodes).

    Raises
    ------
    ConfigError
        Missing or unreadable file, invalid YAML, wrong layout, an unknown key for this node, or a
        value of the wrong type.
    """
    data = load_yaml(path, "params file")
    if not isinstance(data, dict):
        raise ConfigError("expected a mapping '<node name>: {ros__parameters: {...}}'", path=path)
    by_name = {s.name: s for s in specs}
    for node_key, section in data.items():
        name = str(node_key).lstrip("/")
        if name not in (node_name, "**") and not name.endswith("/" + node_name):
            continue
        if not isinstance(section, dict) or set(section) != {"ros__parameters"}:
            raise ConfigError("expected exactly one key 'ros__parameters' under the node name", path=path,
                              key=str(node_key))
        params = section["ros__parameters"]
        if not isinstance(params, dict):
            raise ConfigError("expected a mapping of parameter names to values", path=path,
                              key=f"{node_key}.ros__parameters")
        for key, value in params.items():
            full = f"{node_key}.ros__parameters.{key}"
            if key == "use_sim_time":
                continue
            if key not in by_name:
                raise ConfigError(f"unknown parameter for node '{node_name}' (known: {', '.join(by_name)})",
                                  path=path, key=full)
            spec = by_name[key]
            if spec.choices and isinstance(spec.default, str):
                value = yaml_bool_to_choice(value, spec.choices)
            want = _param_type(spec.default)
            ok = {
                Parameter.Type.BOOL: isinstance(value, bool),
                Parameter.Type.INTEGER: isinstance(value, int) and not isinstance(value, bool),
                Parameter.Type.DOUBLE: isinstance(value, (int, float)) and not isinstance(value, bool),
                Parameter.Type.STRING: isinstance(value, str),
            }.get(want, isinstance(value, list))
            if not ok:
                raise ConfigError(f"expected {want.name.lower()}, got {value!r}", path=path, key=full)
            if spec.choices and value not in spec.choices:
                raise ConfigError(f"must be one of {', '.join(spec.choices)}, got {value!r}", path=path, key=full)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
                    raise ConfigError(f"must be in [{spec.low}, {spec.high}], got {value!r}", path=path, key=full)


def params_files_in(args: Sequence[str]) -> list[str]:
    """Return the ``--params-file`` paths found in a ROS argument list."""
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--params-file"]


def render_params_yaml(node_name: str, specs: Sequence[ParamSpec]) -> str:
    """Render the default ``config/<node>.yaml`` for a spec table: every key, one comment each."""
    import json

    lines = [f"# Parameters of the {node_name} node (defaults). Units in brackets; SI unless stated.",
             f"{node_name}:", "  ros__parameters:"]
    for s in specs:
        value = json.dumps(s.default)  # JSON is YAML; quoted strings stay strings for rcl ('y' is not a bool)
        comment = s.description + (f" [{s.unit}]" if s.unit else "")
        if s.choices:
            comment += f"; one of {', '.join(s.choices)}"
        lines.append(f"    {s.name}: {value}  # {comment}")
    return "\n".join(lines) + "\n"
