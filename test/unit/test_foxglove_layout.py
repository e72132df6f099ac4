"""The Foxglove/Lichtblick layout, checked against the pipeline's interfaces.

Every panel of the mosaic has a configuration; every topic the layout names is one the pipeline
publishes (euc_ros.ros.interfaces); every message path ``/topic.field[.sub]`` names a field of that
topic's message definition (parsed from msg_defs/msg and the standard types' .msg files).
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from euc_ros.ros import interfaces as itf

REPO = Path(__file__).resolve().parents[1].parent
LAYOUT = REPO / "config" / "foxglove" / "euc_pipeline.json"
STANDARD_BODIES = ["H", "CHR", "CHL", "UAR", "UAL", "LAR", "LAL", "HR", "HL", "TR", "TL", "LR", "LL", "E"]


def panels(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    return panels(node["first"]) + panels(node["second"])


def msg_fields(text: str) -> dict[str, str]:
    """field name -> type of a .msg text (constants and comments skipped)."""
    out = {}
    for line in text.splitlines():
        words = line.split("#")[0].split()
        if len(words) < 2 or "=" in words[1]:       # blank, comment, or a constant
            continue
        out[words[1]] = words[0]
    return out


def definitions() -> dict[str, dict[str, str]]:
    import sys

    defs = {f"euc_msgs/{p.stem}": msg_fields(p.read_text()) for p in (REPO / "msg_defs" / "msg").glob("*.msg")}
    share = Path(sys.prefix) / "share"
    for pkg, name in (("std_msgs", "Header"), ("geometry_msgs", "Point"), ("geometry_msgs", "Pose"),
                      ("geometry_msgs", "PoseStamped"), ("geometry_msgs", "Quaternion"),
                      ("builtin_interfaces", "Time")):
        f = share / pkg / "msg" / f"{name}.msg"
        if f.exists():
            defs[f"{pkg}/{name}"] = msg_fields(f.read_text())
    return defs


TOPIC_TYPES = {
    "/" + itf.TORQUE: "euc_msgs/TorqueEstimate",
    "/" + itf.RIDER_STATE: "euc_msgs/RiderState",
    "/" + itf.MOCAP_FRAME: "euc_msgs/MocapFrame",
    itf.DIAGNOSTICS: "diagnostic_msgs/DiagnosticArray",
    itf.TF: "tf2_msgs/TFMessage",
    **{"/" + itf.body_pose_topic(b): "geometry_msgs/PoseStamped" for b in STANDARD_BODIES},
}


@pytest.fixture(scope="module")
def layout():
    return json.loads(LAYOUT.read_text(encoding="utf-8"))


def test_every_panel_has_a_config_and_the_panels_cover_the_pipeline(layout):
    ids = panels(layout["layout"])
    assert sorted(ids) == sorted(layout["configById"]), "mosaic and configById disagree"
    kinds = {i.split("!")[0] for i in ids}
    assert {"3D", "Plot", "DiagnosticSummary", "DiagnosticStatusPanel"} <= kinds
    assert set(layout) >= {"configById", "layout", "globalVariables", "userNodes", "playbackConfig"}


def test_topics_are_published_by_the_pipeline(layout):
    three_d = next(v for k, v in layout["configById"].items() if k.startswith("3D!"))
    assert "/tf" in three_d["topics"] and three_d["followTf"] == "world"
    for topic in three_d["topics"]:
        assert topic in TOPIC_TYPES, topic
    for key, cfg in layout["configById"].items():
        if "topicToRender" in cfg:
            assert cfg["topicToRender"] == itf.DIAGNOSTICS, key


def test_plot_paths_name_real_fields(layout):
    defs = definitions()
    seen = set()
    for key, cfg in layout["configById"].items():
        for path in cfg.get("paths", []):
            m = re.fullmatch(r"(/[\w/]+)\.([\w.]+)", path["value"])
            assert m, path["value"]
            topic, fields = m.groups()
            typ = TOPIC_TYPES[topic]
            for name in fields.split("."):
                assert typ in defs, typ
                assert name in defs[typ], f"{key}: {path['value']}: no field {name!r} in {typ}"
                ftype = defs[typ][name]
                typ = ftype if "/" in ftype else f"{typ.split('/')[0]}/{ftype}"
            assert typ.split("/")[-1] in ("float64", "bool"), path["value"]     # plottable
            seen.add(path["value"])
    for needed in ("m_d1", "m_d2", "residual", "h"):
        assert f"/euc/torque.{needed}" in seen
    assert "/rider/state.phi" in seen
