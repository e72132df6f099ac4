"""config/<node>.yaml holds exactly each node's declared parameters (ParamSpec tables)."""
from pathlib import Path

import pytest
import yaml

from euc_ros.ros.registry import NODES, node_class

CONFIG = Path(__file__).resolve().parents[2] / "config"


@pytest.mark.parametrize("name", sorted(NODES))
def test_config_matches_specs(name):
    try:
        cls = node_class(name)
    except ModuleNotFoundError as exc:
        pytest.skip(f"node {name} not built yet ({exc.name})")
    path = CONFIG / f"{name}.yaml"
    assert path.exists(), f"{path} missing: run python -m euc_ros.ros.registry"
    data = yaml.safe_load(path.read_text())
    keys = set(data[cls.NAME]["ros__parameters"])
    assert keys == {s.name for s in cls.SPECS}
    for spec in cls.SPECS:
        value = data[cls.NAME]["ros__parameters"][spec.name]
        assert value == spec.default or (isinstance(spec.default, float) and value == pytest.approx(spec.default))
