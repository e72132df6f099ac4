"""Reading recordings for the offline analyses (identify, residual): one path for both commands."""
from __future__ import annotations

import sys
from pathlib import Path

from euc_ros.core.errors import InputError


def load_states(session, paths, *, window_s: float, polyorder: int, phi_definition: str = "hinge",
                progress: bool = True, desc: str = "read"):
    """Read recordings, check them against the session and reconstruct their states.

    Every recording is first checked by :func:`euc_ros.core.checks.check_recording`; its warnings are
    kept in ``states.meta["warnings"]`` (see :func:`collect_warnings`). Names are made unique.
    """
    from tqdm import tqdm

    from euc_ros.core.checks import check_recording
    from euc_ros.core.euc.kinematics import reconstruct_states
    from euc_ros.core.io.recordings import load_recording, recording_kind

    for path in paths:
        recording_kind(path)  # fail early, before any long read
    states = []
    # no bar on a non-terminal stderr (disable=None) and none for work that ends (or fails) within 0.5 s,
    # so a refusal stays one line
    bar = tqdm(paths, desc=desc, unit="rec", file=sys.stderr, delay=0.5,
               disable=True if (not progress or len(paths) < 2) else None)
    for path in bar:
        series = load_recording(path, session.world_up)
        warnings = check_recording(series, session, path)
        st = reconstruct_states(series, session, phi_definition=phi_definition, window_s=window_s,
                                polyorder=polyorder)
        if not st.valid.any():
            raise InputError("no frame with the EUC and every rider segment tracked long enough to differentiate",
                             path=path)
        st.name = st.name or Path(path).stem
        st.meta.setdefault("warnings", []).extend(warnings)
        states.append(st)
    seen: dict[str, int] = {}
    for st in states:  # unique names for the report
        k = seen.get(st.name, 0)
        seen[st.name] = k + 1
        if k:
            st.name = f"{st.name}#{k + 1}"
    return states


def collect_warnings(states) -> list[str]:
    """Return every recording's warnings, each prefixed with the recording's name."""
    return [f"{st.name}: {w}" for st in states for w in st.meta.get("warnings", [])]


def print_warnings(warnings, file=None) -> None:
    """Print warnings as ``warning: ...`` lines on stderr."""
    for w in warnings:
        print(f"warning: {w}", file=file or sys.stderr)
