"""Read ROS 2 XML launch files (``*.launch.xml``) into :class:`~euc_ros.ros.launcher.NodeSpec` lists.

The package's launch files are written in the XML format of ROS 2 Jazzy's launch frontend, so that
``ros2 launch euc_ros pipeline.launch.xml`` reads them where launch_ros is installed. ``euc-ros launch``
reads the same files with this module, which implements exactly the subset they use (:data:`SCHEMA`,
:data:`SUBSTITUTIONS`, docs/launch.md) and refuses anything else with the file, the line and the element,
instead of ignoring it.

The subset
----------
``<launch>`` holds ``<arg>``, ``<node>`` and ``<executable>`` elements, in any order:

- ``<arg name default description>`` with ``<choice value>`` children: a launch argument, given on the
  command line as ``name:=value``; without ``default`` it is required.
- ``<node pkg="euc_ros" exec name namespace args output if unless on_exit>`` with ``<param
  from="FILE"/>``, ``<param name value/>``, ``<remap from to/>`` and ``<env name value/>`` children.
- ``<executable cmd name output if unless on_exit>`` with ``<env>`` children: a program that is not a
  node (``cmd`` is split like a shell command line; substitutions stay within one argument).

``on_exit="shutdown"`` makes the process required: when it ends, the launch ends (non-zero if its exit
was not clean). ``if``/``unless`` must come out as true, false, 1 or 0 (case-insensitive), as in
ROS 2. Substitutions: ``$(var NAME)``, ``$(find-pkg-share euc_ros)`` and ``$(eval 'EXPR')`` where EXPR,
after substitution, compares quoted strings (``'a' == 'b'``, ``!=``, ``and``, ``or``, ``not``).

Parameter values are typed as launch_ros types them: the text (after substitution) is read as YAML, so
``1.0`` is a double, ``true`` a bool and ``['a', 'b']`` a list of strings; an empty value is the empty
string. The launcher then converts a value to the type the node declares where that is lossless
(:func:`euc_ros.ros.launcher.typed_parameters`).

Examples
--------
>>> import tempfile, pathlib
>>> f = pathlib.Path(tempfile.mkdtemp()) / "demo.launch.xml"
>>> _ = f.write_text('<launch><arg name="speed" default="1.0" description="forward speed"/>'
...                  '<node pkg="euc_ros" exec="unicycle_sim" name="sim" on_exit="shutdown">'
...                  '<param name="speed" value="$(var speed)"/></node></launch>')
>>> [a.name for a in launch_arguments(f)]
['speed']
>>> spec, = load_launch_file(f, {"speed": "2"})
>>> spec.executable, spec.name, spec.parameters, spec.required
('unicycle_sim', 'sim', {'speed': 2}, True)
"""
from __future__ import annotations

import ast
import shlex
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence, Union

from euc_ros.core.errors import ConfigError
from euc_ros.ros.launcher import NodeSpec
from euc_ros.ros.share import PACKAGE, package_share

#: Every element of the subset: allowed attributes (required ones in ``required``) and child elements.
SCHEMA: dict[str, dict[str, tuple[str, ...]]] = {
    "launch": {"attributes": (), "required": (), "children": ("arg", "node", "executable")},
    "arg": {"attributes": ("name", "default", "description"), "required": ("name",), "children": ("choice",)},
    "choice": {"attributes": ("value",), "required": ("value",), "children": ()},
    "node": {"attributes": ("pkg", "exec", "name", "namespace", "args", "output", "if", "unless", "on_exit"),
             "required": ("pkg", "exec"), "children": ("param", "remap", "env")},
    "executable": {"attributes": ("cmd", "name", "output", "if", "unless", "on_exit"), "required": ("cmd",),
                   "children": ("env",)},
    "param": {"attributes": ("name", "value", "type", "from"), "required": (), "children": ()},
    "remap": {"attributes": ("from", "to"), "required": ("from", "to"), "children": ()},
    "env": {"attributes": ("name", "value"), "required": ("name", "value"), "children": ()},
}

#: The substitutions of the subset and what they take.
SUBSTITUTIONS = {
    "var": "$(var NAME): the value of the launch argument NAME",
    "find-pkg-share": "$(find-pkg-share euc_ros): the package's share directory (launch/, config/)",
    "eval": "$(eval 'EXPR'): True or False of a comparison of quoted strings ('a' == 'b', !=, and, or, not)",
}

#: Values of ``<param type>``: the element type and whether the value is a list (``yaml``: by YAML rules).
PARAM_TYPES: dict[str, tuple[type | None, bool]] = {
    "str": (str, False), "bool": (bool, False), "int": (int, False), "float": (float, False),
    "list_of_str": (str, True), "list_of_bool": (bool, True), "list_of_int": (int, True),
    "list_of_float": (float, True), "yaml": (None, False),
}

#: Values of ``output``: euc-ros launch streams every process to the terminal, prefixed with its name.
OUTPUTS = ("screen", "both")
#: Attributes that are substitution-free literals.
_LITERAL = {("node", "pkg"), ("node", "on_exit"), ("executable", "on_exit"), ("node", "output"),
            ("executable", "output"), ("arg", "name"), ("arg", "description"), ("choice", "value"),
            ("param", "name"), ("param", "type")}


# -- XML with line numbers ------------------------------------------------------------------------


@dataclass
class Element:
    """One XML element of a launch file, with the line it starts on."""

    tag: str
    attrs: dict[str, str]
    line: int
    children: list["Element"] = field(default_factory=list)

    def describe(self) -> str:
        """``<node exec="monitor">``: the tag and its identifying attribute, for error messages."""
        for key in ("name", "exec", "cmd", "from", "value"):
            if key in self.attrs:
                return f'<{self.tag} {key}="{self.attrs[key]}">'
        return f"<{self.tag}>"


def _read_xml(path: Path) -> Element:
    """Parse ``path`` with expat, keeping each element's line; text content is not allowed."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read the launch file: {exc.strerror}", path=path) from None
    parser = xml.parsers.expat.ParserCreate()
    stack: list[Element] = []
    roots: list[Element] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        element = Element(tag, dict(attrs), parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(element)
        stack.append(element)

    def end(_tag: str) -> None:
        stack.pop()

    def text(data: str) -> None:
        if data.strip():
            where = stack[-1].describe() if stack else "the document"
            raise ConfigError(f"{where}: text {data.strip()[:40]!r} inside an element; launch files put "
                              "values in attributes", path=path, line=parser.CurrentLineNumber)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        hint = ""
        if path.suffix in (".yaml", ".yml", ".py"):
            hint = " (euc-ros launch reads ROS 2 XML launch files, *.launch.xml: docs/launch.md)"
        raise ConfigError(f"not well-formed XML: {xml.parsers.expat.ErrorString(exc.code)}, column "
                          f"{exc.offset + 1}{hint}", path=path, line=exc.lineno) from None
    return roots[0]


# -- substitutions --------------------------------------------------------------------------------


@dataclass
class Substitution:
    """``$(name arg ...)``; each argument is a list of text and nested substitutions."""

    name: str
    args: list[list[Union[str, "Substitution"]]]


Parts = list[Union[str, Substitution]]


def _unescape(text: str) -> str:
    """A backslash makes the next character literal (the ROS 2 grammar's escape rule)."""
    out, i = [], 0
    while i < len(text):
        if text[i] == "\\" and i + 1 < len(text):
            i += 1
        out.append(text[i])
        i += 1
    return "".join(out)


class _SubstitutionParser:
    """Recursive descent over the ROS 2 frontend grammar, for the forms the subset needs."""

    def __init__(self, text: str, fail):
        self.s, self.i, self.fail = text, 0, fail

    def _starts_substitution(self) -> bool:
        return self.s.startswith("$(", self.i)

    def _text_until(self, stop: str, *, stop_on_space: bool = False) -> str:
        start = self.i
        while self.i < len(self.s):
            c = self.s[self.i]
            if c == "\\" and self.i + 1 < len(self.s):
                self.i += 2
                continue
            if self._starts_substitution() or c in stop or (stop_on_space and c == " "):
                break
            self.i += 1
        return _unescape(self.s[start:self.i])

    def template(self) -> Parts:
        parts: Parts = []
        while self.i < len(self.s):
            if self._starts_substitution():
                parts.append(self.substitution(quote=None))
            else:
                parts.append(self._text_until(""))
        return parts

    def substitution(self, quote: str | None) -> Substitution:
        start = self.i
        self.i += 2
        name_start = self.i
        while self.i < len(self.s) and (self.s[self.i].isalnum() or self.s[self.i] in "_-"):
            self.i += 1
        name = self.s[name_start:self.i]
        if not name or not name[0].isalpha():
            self.fail(f"'$(' at character {start + 1} must be followed by a substitution name")
        args: list[Parts] = []
        while self.i < len(self.s) and self.s[self.i] == " ":
            self.i += 1
            args.append(self.argument(quote))
        if self.i >= len(self.s) or self.s[self.i] != ")":
            self.fail(f"$({name} ...) starting at character {start + 1} is not closed by ')' (arguments are "
                      "separated by single spaces; quote an argument that holds spaces)")
        self.i += 1
        return Substitution(name, args)

    def argument(self, quote: str | None) -> Parts:
        if quote is None and self.i < len(self.s) and self.s[self.i] in "'\"":
            q = self.s[self.i]
            self.i += 1
            parts: Parts = []
            while self.i < len(self.s) and self.s[self.i] != q:
                if self._starts_substitution():
                    parts.append(self.substitution(quote=q))
                else:
                    parts.append(self._text_until(q))
            if self.i >= len(self.s):
                self.fail(f"the quoted argument opened with {q} is not closed")
            self.i += 1
            return parts
        parts = []
        stops = "()'\"" if quote is None else f"(){quote}"
        while self.i < len(self.s) and self.s[self.i] not in " " + stops:
            if self._starts_substitution():
                parts.append(self.substitution(quote))
            else:
                parts.append(self._text_until(stops, stop_on_space=True))
        if not parts:
            self.fail(f"empty substitution argument at character {self.i + 1}")
        return parts


def _is_literal(parts: Parts) -> bool:
    return all(isinstance(p, str) for p in parts)


def _literal_text(parts: Parts) -> str:
    return "".join(p for p in parts if isinstance(p, str))


# -- the parsed file ------------------------------------------------------------------------------


@dataclass
class LaunchArgument:
    """A launch argument (``<arg>``): ``name:=value`` on the command line.

    Parameters
    ----------
    name : str
    default : str, optional
        Its default as written (substitutions unexpanded); None when the argument is required.
    description : str
    choices : tuple of str
        The values it may take (``<choice>``); empty when free.
    line : int
        Line of its ``<arg>`` element.
    """

    name: str
    default: str | None = None
    description: str = ""
    choices: tuple[str, ...] = ()
    line: int = 0


@dataclass
class LaunchFile:
    """A parsed and checked launch file: its arguments and its ``<node>``/``<executable>`` elements."""

    path: Path
    arguments: list[LaunchArgument]
    processes: list[Element]


class _Context:
    """Error reporting and substitution for one file."""

    def __init__(self, path: Path, declared: Sequence[str] = ()):
        self.path = path
        self.declared = set(declared)

    def error(self, element: Element, message: str) -> ConfigError:
        return ConfigError(f"{element.describe()}: {message}", path=self.path, line=element.line)

    def parse(self, element: Element, attribute: str) -> Parts:
        """Parse an attribute's substitutions and check their names, arity and arguments."""
        text = element.attrs[attribute]

        def fail(message: str):
            raise self.error(element, f"{attribute}=\"{text}\": {message}")

        parts = _SubstitutionParser(text, fail).template() if text else [""]
        for sub in _walk(parts):
            self._check(sub, fail)
        return parts

    def _check(self, sub: Substitution, fail) -> None:
        supported = "; ".join(SUBSTITUTIONS.values())
        if sub.name == "arg":
            fail("$(arg NAME) is ROS 1 syntax: ROS 2 launch files write $(var NAME)")
        if sub.name not in SUBSTITUTIONS:
            fail(f"unsupported substitution $({sub.name} ...) (supported: {supported})")
        if len(sub.args) != 1:
            fail(f"$({sub.name}) takes exactly one argument: {SUBSTITUTIONS[sub.name]}")
        arg = sub.args[0]
        if sub.name == "var":
            if not _is_literal(arg):
                fail("the name in $(var NAME) must be plain text")
            if _literal_text(arg) not in self.declared:
                fail(f"$(var {_literal_text(arg)}) names no <arg> of this file (declared: "
                     f"{', '.join(sorted(self.declared)) or 'none'})")
        elif sub.name == "find-pkg-share" and (not _is_literal(arg) or _literal_text(arg) != PACKAGE):
            fail(f"only $(find-pkg-share {PACKAGE}) is supported: euc-ros launch starts this package's nodes")

    def evaluate(self, element: Element, attribute: str, parts: Parts, values: Mapping[str, str]) -> str:
        """The text of ``parts`` with every substitution performed."""
        out = []
        for part in parts:
            if isinstance(part, str):
                out.append(part)
            elif part.name == "var":
                out.append(values[_literal_text(part.args[0])])
            elif part.name == "find-pkg-share":
                out.append(str(package_share()))
            else:   # eval
                expression = self.evaluate(element, attribute, part.args[0], values)
                out.append(str(self._eval(element, attribute, expression)))
        return "".join(out)

    def _eval(self, element: Element, attribute: str, expression: str) -> bool | str | int | float:
        """Evaluate a comparison of quoted strings, or a choice of two constants by one.

        These are the Python expressions ``$(eval)`` accepts here.
        """
        def bad() -> ConfigError:
            return self.error(element, f"{attribute}: $(eval) of {expression!r}: only comparisons of quoted "
                                       "strings are supported ('a' == 'b', 'a' != 'b', joined with and, or, "
                                       "not), and a choice between two constants by one ('3 if ... else 2'); "
                                       "a value with a quote in it cannot be compared this way")

        try:
            tree = ast.parse(expression.strip(), mode="eval").body
        except SyntaxError:
            raise bad() from None

        def value(node: ast.AST) -> Any:
            if isinstance(node, ast.Constant) and isinstance(node.value, (str, int, float)) \
                    and not isinstance(node.value, bool):
                return node.value
            if isinstance(node, ast.IfExp):
                test = value(node.test)
                if not isinstance(test, bool) or not all(isinstance(n, ast.Constant) for n in (node.body, node.orelse)):
                    raise bad()
                return value(node.body) if test else value(node.orelse)
            if isinstance(node, ast.Compare) and len(node.ops) == 1 and isinstance(node.ops[0], (ast.Eq, ast.NotEq)):
                left, right = value(node.left), value(node.comparators[0])
                if not (isinstance(left, str) and isinstance(right, str)):
                    raise bad()
                return (left == right) == isinstance(node.ops[0], ast.Eq)
            if isinstance(node, ast.BoolOp):
                results = [value(v) for v in node.values]
                if not all(isinstance(r, bool) for r in results):
                    raise bad()
                return all(results) if isinstance(node.op, ast.And) else any(results)
            if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
                inner = value(node.operand)
                if not isinstance(inner, bool):
                    raise bad()
                return not inner
            raise bad()

        result = value(tree)
        if not isinstance(result, bool) and not isinstance(tree, ast.IfExp):
            raise bad()
        return result


def _walk(parts: Parts):
    """Every substitution in ``parts``, nested ones included."""
    for part in parts:
        if isinstance(part, Substitution):
            yield part
            for arg in part.args:
                yield from _walk(arg)


def _check_element(ctx: _Context, element: Element) -> None:
    """Tag, attributes and children against :data:`SCHEMA`, recursively."""
    rule = SCHEMA.get(element.tag)
    if rule is None:
        raise ctx.error(element, f"unsupported element (euc-ros launch reads {', '.join(f'<{t}>' for t in SCHEMA)}; "
                                 "docs/launch.md)")
    unknown = [a for a in element.attrs if a not in rule["attributes"]]
    if unknown:
        allowed = ", ".join(rule["attributes"]) or "none"
        raise ctx.error(element, f"unsupported attribute {unknown[0]!r} (allowed: {allowed})")
    missing = [a for a in rule["required"] if a not in element.attrs]
    if missing:
        raise ctx.error(element, f"missing attribute {missing[0]!r}")
    for child in element.children:
        if child.tag not in rule["children"]:
            if child.tag in SCHEMA:
                allowed = ", ".join(f"<{t}>" for t in rule["children"]) or "nothing"
                raise ctx.error(child, f"not allowed inside <{element.tag}> (allowed there: {allowed})")
        _check_element(ctx, child)


def read_launch_file(path: str | Path) -> LaunchFile:
    """Parse ``path`` and check it against the subset: tags, attributes, substitutions, arguments.

    Raises
    ------
    ConfigError
        Naming the file, the line and the element: malformed XML, an element, attribute or substitution
        outside the subset, ``$(var NAME)`` of an undeclared argument, a default outside the choices, ...
    """
    p = Path(path)
    root = _read_xml(p)
    ctx = _Context(p)
    if root.tag != "launch":
        raise ctx.error(root, "the root element of a launch file is <launch>")
    _check_element(ctx, root)
    arguments: list[LaunchArgument] = []
    for element in root.children:
        if element.tag != "arg":
            continue
        name = element.attrs["name"]
        if not name.isidentifier():
            raise ctx.error(element, "an argument name is a plain identifier (letters, digits, _)")
        if any(a.name == name for a in arguments):
            raise ctx.error(element, f"argument {name!r} is declared twice")
        choices = tuple(c.attrs["value"] for c in element.children)
        default = element.attrs.get("default")
        if default is not None and choices and "$(" not in default and default not in choices:
            raise ctx.error(element, f"default {default!r} is not one of the choices {', '.join(choices)}")
        arguments.append(LaunchArgument(name, default, element.attrs.get("description", ""), choices, element.line))
    ctx.declared = {a.name for a in arguments}
    for element in [root, *_descendants(root)]:
        for attribute in element.attrs:
            if (element.tag, attribute) in _LITERAL:
                if "$(" in element.attrs[attribute]:
                    raise ctx.error(element, f"{attribute} must be plain text, without substitutions")
                continue
            ctx.parse(element, attribute)
        _check_values(ctx, element)
    processes = [e for e in root.children if e.tag in ("node", "executable")]
    if not processes:
        raise ctx.error(root, "no <node> or <executable>: nothing to launch")
    return LaunchFile(p, arguments, processes)


def _descendants(element: Element):
    for child in element.children:
        yield child
        yield from _descendants(child)


def _check_values(ctx: _Context, element: Element) -> None:
    """The fixed-vocabulary attributes and the attribute combinations."""
    a = element.attrs
    if element.tag == "node" and a["pkg"] != PACKAGE:
        raise ctx.error(element, f"pkg must be {PACKAGE!r}: euc-ros launch starts this package's nodes")
    if "on_exit" in a and a["on_exit"] != "shutdown":
        raise ctx.error(element, f"on_exit={a['on_exit']!r}: the only action is on_exit=\"shutdown\"")
    if "output" in a and a["output"] not in OUTPUTS:
        raise ctx.error(element, f"output={a['output']!r}: euc-ros launch streams every process to the "
                                 f"terminal; write output=\"screen\"")
    if "if" in a and "unless" in a:
        raise ctx.error(element, "if and unless cannot be used together")
    if element.tag == "param":
        if ("from" in a) == ("name" in a):
            raise ctx.error(element, "a <param> has either from=\"FILE\" or name=\"NAME\" value=\"VALUE\"")
        if "name" in a and "value" not in a:
            raise ctx.error(element, "missing attribute 'value' (nested <param> groups are not supported)")
        if "from" in a and ("value" in a or "type" in a):
            raise ctx.error(element, "value and type go with name=, not with from=")
        if "type" in a and a["type"] not in PARAM_TYPES:
            raise ctx.error(element, f"type={a['type']!r}: one of {', '.join(PARAM_TYPES)}")
    if element.tag == "node":
        params = [c for c in element.children if c.tag == "param"]
        named = [i for i, c in enumerate(params) if "name" in c.attrs]
        files = [i for i, c in enumerate(params) if "from" in c.attrs]
        if named and files and max(files) > min(named):
            raise ctx.error(params[max(files)], "put every <param from=...> before the <param name=...> "
                                                "elements: single parameters override the files")


# -- resolving ------------------------------------------------------------------------------------


def find_launch_file(name: str | Path) -> Path:
    """A launch file by path, or by bare file name in the package's ``launch/`` directory.

    Raises
    ------
    ConfigError
        When neither exists; the message lists the package's launch files.
    """
    p = Path(name)
    if p.is_file():
        return p
    if len(p.parts) == 1:
        try:
            launch_dir = package_share() / "launch"
        except ConfigError:
            launch_dir = None
        if launch_dir is not None and (launch_dir / p).is_file():
            return launch_dir / p
        if launch_dir is not None:
            known = ", ".join(sorted(f.name for f in launch_dir.glob("*.launch.xml"))) or "none"
            raise ConfigError(f"no launch file {str(name)!r} here or in {launch_dir} (the package's: {known})")
    raise ConfigError(f"no launch file {str(name)!r}")


def launch_arguments(path: str | Path) -> list[LaunchArgument]:
    """The ``<arg>`` declarations of a launch file, in file order (the file is checked first)."""
    return read_launch_file(path).arguments


def parse_launch_arguments(items: Sequence[str]) -> dict[str, str]:
    """``['source:=csv', 'bag:=out']`` -> ``{'source': 'csv', 'bag': 'out'}``.

    The ros2 launch syntax; the last of duplicates wins.
    """
    out = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            raise ConfigError(f"launch arguments are written name:=value, got {item!r}", key=item)
        out[name] = value
    return out


def resolve_arguments(launch: LaunchFile, given: Mapping[str, str]) -> dict[str, str]:
    """The value of every argument: given, else its default (substitutions performed, in file order).

    Raises
    ------
    ConfigError
        An undeclared name, a required argument not given, a value outside the choices.
    """
    declared = {a.name: a for a in launch.arguments}
    for name in given:
        if name not in declared:
            raise ConfigError(f"no launch argument {name!r} (declared: {', '.join(declared) or 'none'}; "
                              "euc-ros launch FILE --show-args lists them)", path=launch.path, key=name)
    ctx = _Context(launch.path, declared)
    values: dict[str, str] = {}
    for arg in launch.arguments:
        if arg.name in given:
            value = given[arg.name]
        elif arg.default is None:
            raise ConfigError(f"launch argument {arg.name!r} is required ({arg.description}): add "
                              f"{arg.name}:=VALUE", path=launch.path, key=arg.name)
        else:
            element = Element("arg", {"name": arg.name, "default": arg.default}, arg.line)
            parts = ctx.parse(element, "default")
            if any(s.name == "var" and _literal_text(s.args[0]) not in values for s in _walk(parts)):
                raise ctx.error(element, "a default can use only the arguments declared before it")
            value = ctx.evaluate(element, "default", parts, values)
        if arg.choices and value not in arg.choices:
            raise ConfigError(f"launch argument {arg.name!r} must be one of {', '.join(arg.choices)}, got "
                              f"{value!r}", path=launch.path, key=arg.name)
        values[arg.name] = value
    return values


def _condition(ctx: _Context, element: Element, values: Mapping[str, str]) -> bool:
    """Whether ``if``/``unless`` let the element start."""
    for attribute, wanted in (("if", True), ("unless", False)):
        if attribute in element.attrs:
            text = ctx.evaluate(element, attribute, ctx.parse(element, attribute), values).strip().lower()
            if text not in ("true", "1", "false", "0"):
                raise ctx.error(element, f"{attribute}=\"{element.attrs[attribute]}\" gave {text!r}: a "
                                         "condition must be true, false, 1 or 0 (compare strings with "
                                         "$(eval '\\'$(var NAME)\\' == \\'\\''))")
            return (text in ("true", "1")) == wanted
    return True


def _split_command(ctx: _Context, element: Element, attribute: str, values: Mapping[str, str]) -> list[str]:
    """Split a command line as ROS 2 does: text by shell rules, a substitution's value never split."""
    result: list[str] = []
    current: list[str] = []
    pending = False            # current holds a piece
    for part in ctx.parse(element, attribute):
        if isinstance(part, Substitution):
            current.append(ctx.evaluate(element, attribute, [part], values))
            pending = True
            continue
        try:
            tokens = shlex.split(part)
        except ValueError as exc:
            raise ctx.error(element, f"{attribute}: {exc}") from None
        if not tokens:
            if pending:
                result.append("".join(current))
                current, pending = [], False
            continue
        if part[0].isspace() and pending:
            result.append("".join(current))
            current, pending = [], False
        current.append(tokens[0])
        pending = True
        if len(tokens) > 1:
            result.append("".join(current))
            result.extend(tokens[1:-1])
            current, pending = [tokens[-1]], True
        if part[-1].isspace():
            result.append("".join(current))
            current, pending = [], False
    if pending:
        result.append("".join(current))
    return result


def _parameter_value(ctx: _Context, element: Element, values: Mapping[str, str]) -> Any:
    """A ``<param name value [type]>`` value typed as launch_ros types it.

    Without ``type`` (or ``type="yaml"``) the text is read as YAML: ``1`` an int, ``1.0`` a double,
    ``true`` a bool, ``['a']`` a list; ``type="str"`` keeps the text as it is (``001`` stays a string),
    ``float``/``int``/``bool`` and ``list_of_*`` convert to that type or fail.
    """
    import yaml

    parts = ctx.parse(element, "value")
    text = ctx.evaluate(element, "value", parts, values)
    kind, is_list = PARAM_TYPES[element.attrs.get("type", "yaml")]
    if kind is str and not is_list:
        return text
    if kind in (int, float) and not is_list:
        try:
            return kind(text)
        except ValueError:
            raise ctx.error(element, f"value {text!r} is not {'an int' if kind is int else 'a float'}") from None
    if not text and kind is None:
        return ""
    if kind is bool and not is_list:
        text = {"1": "true", "0": "false"}.get(text, text)
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        if _is_literal(parts) and kind is None:
            return text
        raise ctx.error(element, f"value {text!r} is not valid YAML; quote a string value or add "
                                 "type=\"str\"") from None
    scalar = (bool, int, float, str)
    if kind is not None:
        ok = (isinstance(value, list) and bool(value) and all(type(v) is kind for v in value)) if is_list \
            else type(value) is kind
        if not ok:
            want = f"a non-empty list of {kind.__name__}" if is_list else kind.__name__
            raise ctx.error(element, f"value {text!r} is not {want} (type={element.attrs['type']!r})")
        return value
    if isinstance(value, scalar):
        return value
    if isinstance(value, list):
        if not value:
            raise ctx.error(element, "an empty list has no element type: give at least one item (e.g. [''])")
        kinds = {type(v) for v in value}
        if len(kinds) == 1 and kinds <= set(scalar):
            return value
        raise ctx.error(element, f"list {text!r} mixes types or nests: give items of one type (bool, int, "
                                 "float or string)")
    raise ctx.error(element, f"value {text!r} is not a parameter value (a bool, int, float, string or list of "
                             "one of them); quote a string value or add type=\"str\"")


def _process(ctx: _Context, element: Element, values: Mapping[str, str]) -> NodeSpec:
    """The NodeSpec of one ``<node>`` or ``<executable>`` element."""
    a = element.attrs

    def text(attribute: str) -> str | None:
        if attribute not in a:
            return None
        return ctx.evaluate(element, attribute, ctx.parse(element, attribute), values)

    env = {}
    params_files: list[str] = []
    parameters: dict[str, Any] = {}
    remaps: dict[str, str] = {}
    for child in element.children:
        if child.tag == "env":
            env[_text_of(ctx, child, "name", values)] = _text_of(ctx, child, "value", values)
        elif child.tag == "remap":
            remaps[_text_of(ctx, child, "from", values)] = _text_of(ctx, child, "to", values)
        elif "from" in child.attrs:
            f = Path(_text_of(ctx, child, "from", values))
            if not f.is_file():
                raise ctx.error(child, f"params file {f} does not exist")
            params_files.append(str(f))
        else:
            parameters[child.attrs["name"]] = _parameter_value(ctx, child, values)
    required = a.get("on_exit") == "shutdown"
    if element.tag == "executable":
        argv = _split_command(ctx, element, "cmd", values)
        if not argv:
            raise ctx.error(element, "cmd is empty")
        return NodeSpec(argv[0], name=text("name") or None, args=argv[1:], env=env, required=required,
                        ros_args=False)
    executable = text("exec")
    if not executable:
        raise ctx.error(element, "exec is empty")
    return NodeSpec(executable, name=text("name") or None,
                    params_file=params_files[0] if params_files else None, params_files=tuple(params_files[1:]),
                    parameters=parameters, remaps=remaps, namespace=text("namespace") or None, required=required,
                    env=env, args=_split_command(ctx, element, "args", values) if "args" in a else ())


def _text_of(ctx: _Context, element: Element, attribute: str, values: Mapping[str, str]) -> str:
    """An attribute's text with its substitutions performed."""
    return ctx.evaluate(element, attribute, ctx.parse(element, attribute), values)


def load_launch_file(path: str | Path, arguments: Mapping[str, str] | None = None) -> list[NodeSpec]:
    """The processes a launch file starts with these arguments, in file order.

    Parameters
    ----------
    path : str or Path
        A ``*.launch.xml`` file.
    arguments : mapping, optional
        ``name -> value`` launch arguments (the command line's ``name:=value``); the others take their
        defaults.

    Returns
    -------
    list of NodeSpec
        One per ``<node>``/``<executable>`` whose ``if``/``unless`` lets it start.

    Raises
    ------
    ConfigError
        Naming the file, line and element (or the argument) that is wrong.
    """
    launch = read_launch_file(path)
    values = resolve_arguments(launch, dict(arguments or {}))
    ctx = _Context(launch.path, values)
    return [_process(ctx, e, values) for e in launch.processes if _condition(ctx, e, values)]
