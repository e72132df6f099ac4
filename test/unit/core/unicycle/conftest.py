"""Fixtures of the unicycle tests: Table I parameters, random states, the (slow, cached) derivations."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.unicycle.dynamics import STATE_NAMES, UnicycleParams


@pytest.fixture(scope="session")
def params() -> UnicycleParams:
    """Table I of the steering paper."""
    return UnicycleParams()


def _random_states(n: int, seed: int, max_tilt_deg: float = 80.0) -> np.ndarray:
    """Random unicycle states (10, n) well inside the model's domain, covering large rates."""
    rng = np.random.default_rng(seed)
    x = np.empty((len(STATE_NAMES), n))
    x[0:3] = rng.uniform(-10, 10, (3, n))             # omega [rad/s]
    x[3] = np.radians(rng.uniform(-max_tilt_deg, max_tilt_deg, n))
    x[4] = rng.uniform(-3, 3, n)                       # sigma [m/s]
    x[5] = rng.uniform(-0.6, 0.6, n)                   # r [m]
    x[6] = rng.uniform(-np.pi, np.pi, n)               # psi
    x[7] = rng.uniform(-np.pi, np.pi, n)               # phi
    x[8:10] = rng.uniform(-20, 20, (2, n))             # position [m]
    return x


@pytest.fixture(scope="session")
def random_states():
    """``random_states(n, seed, max_tilt_deg=80)`` -> random unicycle states (10, n)."""
    return _random_states


@pytest.fixture(scope="session")
def kane():
    from euc_ros.core.unicycle.derivation import derive_kane

    return derive_kane(True)


@pytest.fixture(scope="session")
def kane_wheel():
    from euc_ros.core.unicycle.derivation import derive_kane

    return derive_kane(False)
