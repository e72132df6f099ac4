"""The documentation's CSV replays through a launch end by themselves: a pipeline launched with
``source:=csv`` ends only when mocap_ingest exits, which it does after the last frame only with
``exit_when_done`` (config/mocap_ingest.yaml has it false)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DOCS = sorted((REPO / "docs").rglob("*.md")) + [REPO / "README.md"]


def launch_commands(text: str) -> list[str]:
    """Every ``euc-ros launch`` / ``ros2 launch`` command line of a text, continuation lines joined."""
    text = re.sub(r"\\\n\s*", " ", text)
    return [line.strip() for line in text.splitlines() if re.search(r"\b(euc-ros|ros2) launch\b", line)]


def ends_by_itself(command: str) -> bool:
    return "exit_when_done:=true" in command or "--duration" in command


def mocap_ingest_nodes(text: str) -> list[str]:
    """The ``<node ... exec="mocap_ingest"> ... </node>`` elements of a text's XML examples."""
    return re.findall(r'<node[^>]*exec="mocap_ingest".*?</node>', text, flags=re.S)


def test_the_checks_find_a_replay_that_never_ends():
    never = "euc-ros launch pipeline.launch.xml session:=s.yaml h:=0.6 source:=csv \\\n    csv_path:=ride.csv\n"
    assert not ends_by_itself(launch_commands(never)[0])
    assert ends_by_itself(launch_commands(never.replace("ride.csv", "ride.csv exit_when_done:=true"))[0])
    node = '<node pkg="euc_ros" exec="mocap_ingest">\n  <param name="csv_path" value="r.csv"/>\n</node>'
    assert mocap_ingest_nodes(node) == [node] and 'name="exit_when_done" value="true"' not in node


def test_mocap_ingest_does_not_end_a_replay_by_default():
    config = yaml.safe_load((REPO / "config" / "mocap_ingest.yaml").read_text(encoding="utf-8"))
    assert config["mocap_ingest"]["ros__parameters"]["exit_when_done"] is False


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(REPO)))
def test_every_csv_replay_of_the_docs_ends(doc):
    text = doc.read_text(encoding="utf-8")
    never = [c for c in launch_commands(text) if "source:=csv" in c and not ends_by_itself(c)]
    never += [n for n in mocap_ingest_nodes(text)
              if 'name="csv_path"' in n and not re.search(r'name="exit_when_done"\s+value="true"', n)]
    assert not never, f"{doc.relative_to(REPO)}: a CSV replay that never ends:\n" + "\n".join(never)
