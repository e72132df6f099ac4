"""Launch nodes as separate OS processes (the process side of ``euc-ros launch``).

Each node runs its console script with ``--ros-args`` (params files, overrides, remaps, name and
namespace). Output lines are prefixed with the node name and streamed. SIGINT, SIGTERM and SIGHUP
(a closed terminal, a lost SSH session) to the launcher stop every node; shutdown escalates SIGINT ->
SIGTERM -> SIGKILL in reverse start order. When a ``required`` node exits, everything is shut down
and the launcher returns non-zero if that exit was not clean; after a clean exit (a replay that has ended) the
others are first left to finish what they have queued, until they are idle (:meth:`Launcher.settle`).

Children never outlive the launcher: each is started with the Linux parent-death signal set to
SIGTERM (``prctl(PR_SET_PDEATHSIG)``), so a launcher killed by SIGKILL or a crash still ends them, and
they end as on SIGTERM (a recorder closes its bag with its metadata). The signal fires when the
*thread* that started the child ends: start launchers from a thread that outlives them (the main
thread does).

Parameter overrides of the package's own nodes are converted to the type the node declares
(:func:`typed_parameters`): ``rate_factor: 2`` reaches a node that declares a double as ``2.0``, which
rclpy would otherwise refuse. Launch files are read by :mod:`euc_ros.ros.launch_file`.

Examples
--------
>>> spec = NodeSpec("my_tool", name="rec", parameters={"output": "/tmp/bag"})
>>> spec.command()
['my_tool', '--ros-args', '-r', '__node:=rec', '-p', "output:='/tmp/bag'"]
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Iterable, Mapping, Sequence

import psutil

from euc_ros.core.errors import ConfigError

#: Grace periods of the shutdown escalation [s].
SIGINT_GRACE_S = 5.0
SIGTERM_GRACE_S = 3.0
#: When a required node finishes cleanly (a replay at its end), the others are stopped once each has used under
#: :data:`IDLE_CPU_SHARE` of a core over :data:`IDLE_WINDOW_S` (a node still working through a backlog of messages
#: uses a whole core), or after :data:`SETTLE_MAX_S`: what is still queued downstream is processed and recorded, not
#: lost to the stop. An idle node (a 1 Hz diagnostics timer, DDS's own threads) uses a few per cent.
IDLE_CPU_SHARE = 0.2
IDLE_WINDOW_S = 0.3
SETTLE_MAX_S = 20.0


def tree_cpu_seconds(pid: int) -> float | None:
    """CPU time [s] (user + system) used so far by process ``pid`` and its live descendants; None once it is gone.

    Parameters
    ----------
    pid : int
        A launched node's process.

    Returns
    -------
    float or None
    """
    try:
        root = psutil.Process(pid)
        procs = [root, *root.children(recursive=True)]
    except psutil.Error:
        return None
    total = 0.0
    for proc in procs:
        try:
            t = proc.cpu_times()
        except psutil.Error:        # a descendant that ended while read
            continue
        total += t.user + t.system
    return total


_PR_SET_PDEATHSIG = 1
_libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True) if sys.platform == "linux" else None


def _die_with_parent(parent_pid: int):
    """A ``preexec_fn``: SIGTERM to the child when its parent ends; the parent may already be gone."""
    def preexec() -> None:
        if _libc is not None:
            _libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        if os.getppid() != parent_pid:      # the parent died before prctl took effect
            os.kill(os.getpid(), signal.SIGTERM)
    return preexec


def _format_value(value: Any) -> str:
    """Format a parameter override value in ROS YAML syntax for ``-p name:=value``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_format_value(v) for v in value) + "]"
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


def _package_lib_dirs() -> list[Path]:
    """Where ``ros2 run euc_ros X`` would look.

    ``<prefix>/lib/euc_ros`` of the install this module comes from (a colcon install space:
    ``<prefix>/lib/python3.X/site-packages/euc_ros``), then of every ``AMENT_PREFIX_PATH`` entry that indexes
    the package.
    """
    package = Path(__file__).resolve().parents[1]          # .../euc_ros
    dirs = []
    if package.parent.name in ("site-packages", "dist-packages"):
        dirs.append(package.parents[3] / "lib" / "euc_ros")
    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        if (Path(prefix) / "share" / "ament_index" / "resource_index" / "packages" / "euc_ros").exists():
            dirs.append(Path(prefix) / "lib" / "euc_ros")
    return dirs


def resolve_executable(executable: str) -> str:
    """Find a node executable or console script.

    In this install's ``lib/euc_ros`` (colcon, as ``ros2 run`` does), next to this Python (the venv's bin, pip
    installs), then on PATH.
    """
    if os.sep in executable:
        return executable
    candidates = [d / executable for d in _package_lib_dirs()] + [Path(sys.executable).parent / executable]
    for candidate in candidates:
        if candidate.exists():
            return str(candidate)
    found = shutil.which(executable)
    if found is None:
        raise ConfigError(f"executable {executable!r} not found in {', '.join(str(c.parent) for c in candidates)} "
                          "or on PATH", key="executable")
    return found


def declared_parameters(executable: str, args: Sequence[str] = ()) -> dict[str, Any] | None:
    """The declared defaults (by parameter name) of a node executable of this package.

    They are read from the package's ``config/<node>.yaml``, which lists every parameter of the node's
    ParamSpec table with its default (``python -m euc_ros.ros.registry`` writes them; a unit test holds
    them to the tables). Importing the node modules instead would load rclpy into the launcher, and
    importing :mod:`euc_ros.nodes` would set its BLAS thread variables for every launched program.

    Parameters
    ----------
    executable : str
        Console script name or path; its file name is the node name (``config/<name>.yaml``).
        ``pipeline_container`` declares the parameters of the nodes it composes: those of ``--nodes a,b``
        in ``args``, else its default composition.
    args : sequence of str
        The program arguments before ``--ros-args``.

    Returns
    -------
    dict or None
        None for a program that is not one of the package's nodes (no defaults file of that name).
    """
    name = Path(executable).name
    nodes = [name]
    if name == "pipeline_container":
        nodes = list(CONTAINER_DEFAULT_NODES)
        args = list(args)
        for i, arg in enumerate(args):
            if arg == "--nodes" and i + 1 < len(args):
                nodes = args[i + 1].split(",")
            elif arg.startswith("--nodes="):
                nodes = arg.partition("=")[2].split(",")
    out: dict[str, Any] = {}
    for node in (n.strip() for n in nodes):
        defaults = _config_defaults(node) if node.isidentifier() else None
        if defaults is None:
            return None
        for key, value in defaults.items():
            out.setdefault(key, value)
    return out


#: The nodes ``pipeline_container`` composes without ``--nodes`` (``euc_ros.nodes.container.DEFAULT_NODES``,
#: which imports rclpy).
CONTAINER_DEFAULT_NODES = ("mocap_ingest", "rider_state", "torque_estimator")


def _config_defaults(node: str) -> dict[str, Any] | None:
    """``ros__parameters`` of the package's ``config/<node>.yaml``; None when it cannot be read."""
    import yaml

    from euc_ros.ros.share import package_share

    try:
        path = package_share() / "config" / f"{node}.yaml"
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        params = data[node]["ros__parameters"]
    except (ConfigError, OSError, yaml.YAMLError, KeyError, TypeError):
        return None
    return params if isinstance(params, dict) else None


def _element_type(default: Any) -> type:
    """The Python type of a declared default as rclpy types it (bool before int: a bool is an int)."""
    for kind in (bool, int, float, str):
        if isinstance(default, kind):
            return kind
    raise TypeError(default)


def _coerce_scalar(value: Any, kind: type) -> Any:
    if isinstance(value, bool) or kind is bool:
        return value      # a string choice spelt as a bare y/n is mapped back by the node itself
    if kind is float and isinstance(value, int):
        return float(value)
    if kind is int and isinstance(value, float) and value.is_integer():
        return int(value)
    if kind is str and isinstance(value, (int, float)):
        return str(value)
    return value


def coerce_parameter(default: Any, value: Any) -> Any:
    """Convert an override ``value`` to the type of the declared ``default``, where that is lossless.

    An int for a double (``2`` -> ``2.0``), a whole float for an integer, a number for a string
    (``1`` -> ``'1'``), element by element for arrays. Other values are returned unchanged: the node
    refuses them with the parameter's name.

    Examples
    --------
    >>> coerce_parameter(1.0, 2), coerce_parameter([""], [1, "a"]), coerce_parameter(0, 3.0)
    (2.0, ['1', 'a'], 3)
    """
    if isinstance(default, (list, tuple)):
        if not isinstance(value, (list, tuple)):
            return value
        kinds = {_element_type(d) for d in default}
        if not default or kinds == {str}:
            kind: type = str
        elif kinds in ({bool}, {int}):
            kind = kinds.pop()
        else:
            kind = float
        return [_coerce_scalar(v, kind) for v in value]
    try:
        kind = _element_type(default)
    except TypeError:
        return value
    return _coerce_scalar(value, kind)


def typed_parameters(executable: str, parameters: Mapping[str, Any], args: Sequence[str] = ()) -> dict[str, Any]:
    """``parameters`` with each value converted to the type its node declares (:func:`coerce_parameter`).

    Overrides of programs other than the package's nodes, and of undeclared names, are passed unchanged.
    """
    declared = declared_parameters(executable, args) if parameters else None
    if not declared:
        return dict(parameters)
    return {k: coerce_parameter(declared[k], v) if k in declared else v for k, v in parameters.items()}


@dataclass
class NodeSpec:
    """One process to launch.

    Parameters
    ----------
    executable : str
        Console script (``mocap_ingest``) or path.
    name : str, optional
        Node name (``__node:=``) and log prefix; defaults to the executable name.
    params_file : str, optional
        YAML passed with ``--params-file``.
    params_files : sequence of str
        Further ``--params-file`` YAMLs, after ``params_file`` (a container: one per node).
    parameters : mapping
        ``-p name:=value`` overrides (applied after the params files); for the package's nodes each value
        is converted to the declared type first (:func:`typed_parameters`).
    remaps : mapping
        ``-r from:=to`` topic remaps.
    namespace : str, optional
    required : bool
        If it exits, the launch ends (non-zero if its exit code was not 0).
    env : mapping
        Extra environment variables.
    args : sequence of str
        Arguments before ``--ros-args`` (for non-node programs, e.g. a test helper).
    ros_args : bool
        Append ``--ros-args ...`` (False for plain programs).
    """

    executable: str
    name: str | None = None
    params_file: str | None = None
    params_files: Sequence[str] = ()
    parameters: Mapping[str, Any] = field(default_factory=dict)
    remaps: Mapping[str, str] = field(default_factory=dict)
    namespace: str | None = None
    required: bool = True
    env: Mapping[str, str] = field(default_factory=dict)
    args: Sequence[str] = ()
    ros_args: bool = True

    @property
    def label(self) -> str:
        """Log prefix."""
        return self.name or Path(self.executable).name

    def command(self) -> list[str]:
        """Return the argv of the process (executable unresolved)."""
        cmd = [self.executable, *self.args]
        if not self.ros_args:
            return cmd
        cmd.append("--ros-args")
        if self.name:
            cmd += ["-r", f"__node:={self.name}"]
        if self.namespace:
            cmd += ["-r", f"__ns:={self.namespace}"]
        for src, dst in self.remaps.items():
            cmd += ["-r", f"{src}:={dst}"]
        for path in ([self.params_file] if self.params_file else []) + list(self.params_files):
            cmd += ["--params-file", str(path)]
        for key, value in typed_parameters(self.executable, self.parameters, self.args).items():
            cmd += ["-p", f"{key}:={_format_value(value)}"]
        return cmd


class Launcher:
    """Start, watch and stop a set of node processes.

    Use as a context manager (``with Launcher(specs) as l: l.wait(...)``) so children are always
    stopped. ``exit_codes`` maps labels to exit codes once processes end.
    """

    def __init__(self, specs: Iterable[NodeSpec], *, stream: IO[str] | None = None, prefix_logs: bool = True):
        self.specs = list(specs)
        labels = [s.label for s in self.specs]
        if len(set(labels)) != len(labels):
            raise ConfigError(f"node names must be unique, got {labels}", key="nodes")
        self.stream = stream if stream is not None else sys.stdout
        self.prefix_logs = prefix_logs
        self.procs: dict[str, subprocess.Popen] = {}
        self.exit_codes: dict[str, int] = {}
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()
        self.failed: str | None = None

    # -- lifecycle -------------------------------------------------------------------------------
    def start(self) -> "Launcher":
        """Start every process in order."""
        commands = [spec.command() for spec in self.specs]
        for cmd in commands:
            cmd[0] = resolve_executable(cmd[0])          # all found before any starts
        for spec, cmd in zip(self.specs, commands):
            env = dict(os.environ)
            env.update({k: str(v) for k, v in spec.env.items()})
            env.setdefault("PYTHONUNBUFFERED", "1")
            env.setdefault("RCUTILS_LOGGING_BUFFERED_STREAM", "0")
            # a session of its own: a terminal's SIGINT/SIGHUP reach the launcher only, which stops the
            # nodes in order; the parent-death signal covers the launcher's own death
            proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                    env=env, start_new_session=True, text=True, bufsize=1, errors="replace",
                                    preexec_fn=_die_with_parent(os.getpid()))
            self.procs[spec.label] = proc
            t = threading.Thread(target=self._pump, args=(spec.label, proc), daemon=True)
            t.start()
            self._threads.append(t)
        return self

    def _pump(self, label: str, proc: subprocess.Popen) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:   # always drained: a child blocked on a full pipe would never stop
            self.say(f"[{label}] {line}" if self.prefix_logs else line)

    def say(self, text: str) -> None:
        """Write to the log stream; a closed terminal (EIO, EPIPE) loses the text, never the launch."""
        with self._lock:
            try:
                self.stream.write(text)
                self.stream.flush()
            except (OSError, ValueError):
                pass

    def poll(self) -> bool:
        """Update exit codes; return True while the launch should go on."""
        for spec in self.specs:
            proc = self.procs.get(spec.label)
            if proc is None or spec.label in self.exit_codes:
                continue
            code = proc.poll()
            if code is not None:
                self.exit_codes[spec.label] = code
                if spec.required and self.failed is None:
                    self.failed = spec.label
        if self.failed is not None:
            return False
        return any(lbl not in self.exit_codes for lbl in self.procs)

    def wait(self, timeout: float | None = None, *, until=None, period: float = 0.05) -> bool:
        """Wait until a required node exits, all exit, ``until()`` is true or ``timeout`` passes.

        Returns True if ``until`` became true (or, without ``until``, if processes ended).
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if until is not None and until():
                return True
            if not self.poll():
                return until is None
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(period)

    def settle(self, max_s: float = SETTLE_MAX_S, window_s: float = IDLE_WINDOW_S,
               share: float = IDLE_CPU_SHARE) -> float:
        """Wait until every running node is idle (under ``share`` of a core over ``window_s``), at most ``max_s``.

        Parameters
        ----------
        max_s : float
            Longest wait [s].
        window_s : float
            Window of the CPU measurement [s].
        share : float
            CPU share of one core under which a node is idle.

        Returns
        -------
        float
            The time waited [s].
        """
        t0 = time.monotonic()
        last = None
        while time.monotonic() - t0 < max_s:
            alive = [p.pid for p in self.procs.values() if p.poll() is None]
            now = {pid: tree_cpu_seconds(pid) for pid in alive}
            if not alive or any(v is None for v in now.values()):
                break
            if last is not None and all(now[p] - last.get(p, 0.0) < share * window_s for p in alive):
                break
            last = now
            time.sleep(window_s)
        return time.monotonic() - t0

    def shutdown(self, sigint_grace_s: float = SIGINT_GRACE_S, sigterm_grace_s: float = SIGTERM_GRACE_S) -> None:
        """Stop children in reverse start order: SIGINT, then SIGTERM, then SIGKILL."""
        for sig, grace in ((signal.SIGINT, sigint_grace_s), (signal.SIGTERM, sigterm_grace_s),
                           (signal.SIGKILL, 2.0)):
            alive = [(lbl, p) for lbl, p in reversed(list(self.procs.items())) if p.poll() is None]
            if not alive:
                break
            for _, p in alive:
                try:
                    os.killpg(p.pid, sig)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + grace
            while time.monotonic() < deadline and any(p.poll() is None for _, p in alive):
                time.sleep(0.02)
        for lbl, p in self.procs.items():
            try:
                code = p.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                code = -9
            self.exit_codes.setdefault(lbl, code)
        for t in self._threads:
            t.join(timeout=1.0)

    def return_code(self) -> int:
        """0 if every required node exited cleanly (code 0), else 1."""
        bad = [s.label for s in self.specs if s.required and self.exit_codes.get(s.label) not in (0, None)]
        return 1 if bad else 0

    def __enter__(self) -> "Launcher":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.shutdown()


#: Signals that stop a launch: Ctrl-C, ``kill``, and a closed terminal or lost SSH session.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def run(specs: Iterable[NodeSpec], *, duration: float | None = None, stream: IO[str] | None = None) -> int:
    """Launch ``specs`` and run until done, ``duration`` or a stop signal; return the exit code.

    SIGINT, SIGTERM and SIGHUP stop every node in order (:data:`STOP_SIGNALS`); a required node that
    ends stops the others, with one line saying which and its exit code; one that finishes cleanly stops them
    once they are idle (:meth:`Launcher.settle`), so what they still had queued is not lost.
    """
    launcher = Launcher(specs, stream=stream)
    stop = threading.Event()
    received: list[int] = []

    def _forward(signum, _frame):
        received.append(signum)
        stop.set()

    old = {s: signal.signal(s, _forward) for s in STOP_SIGNALS}
    try:
        launcher.start()
        deadline = None if duration is None else time.monotonic() + duration
        while not stop.is_set() and launcher.poll():
            if deadline is not None and time.monotonic() >= deadline:
                break
            time.sleep(0.05)
        if launcher.failed is not None and not received:
            code = launcher.exit_codes.get(launcher.failed)
            how = "finished" if code == 0 else f"exited with code {code}"
            if code == 0:       # a clean end: what is queued downstream is processed before the stop
                waited = launcher.settle()
                launcher.say(f"launch: {launcher.failed} finished; the other nodes idle after {waited:.1f} s\n")
            launcher.say(f"launch: {launcher.failed} {how}: stopping the other nodes\n")
    finally:
        launcher.shutdown()
        for s, h in old.items():
            signal.signal(s, h)
    return launcher.return_code()
