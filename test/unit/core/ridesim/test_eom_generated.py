"""The printed truth equations (eom_generated.py) are the sympy derivation's, as text and as numbers."""
# covers: euc_ros/core/ridesim/eom_codegen.py
# covers: euc_ros/core/ridesim/eom_derivation.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.ridesim import eom_codegen, eom_generated
from euc_ros.core.ridesim.truth_model import PlanarParams, _numeric


def test_the_file_is_what_the_derivation_prints():
    """Regenerate with ``python -m euc_ros.core.ridesim.eom_codegen`` after changing a derivation."""
    assert eom_codegen.TARGET.read_text(encoding="utf-8") == eom_codegen.generated_source()


@pytest.mark.parametrize("model,func", [(m, f) for m, funcs in eom_codegen.MODELS for f in funcs])
def test_generated_functions_equal_the_lambdified_derivation(model, func):
    derived = _numeric(model, "sympy")
    generated = getattr(eom_generated, f"{model}_{func}")
    lam = getattr(derived, f"{func}_v")
    rng = np.random.default_rng(1)
    n_args = generated.__code__.co_argcount - len(PlanarParams().as_tuple())
    states = rng.uniform(-1.0, 1.0, (n_args, 200))
    args = (*states, *PlanarParams().as_tuple())
    a = np.broadcast_arrays(*(np.asarray(v, float) for v in generated(*args)))
    b = np.broadcast_arrays(*(np.asarray(v, float) for v in lam(*args)))
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        # the same expressions evaluated in another order: equal to a few units of rounding
        np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-13 * max(1.0, np.abs(y).max()))


def test_scalar_versions_are_the_same_functions_on_floats():
    num = _numeric("planar", "generated")
    args = (0.1, -0.2, 0.5, 0.3, -0.4, 0.61, 0.01, 0.02, 0.0, -9.81, *PlanarParams().as_tuple())
    assert np.allclose(num.bias_s(*args), num.bias_v(*args), rtol=0, atol=1e-12)
    assert all(isinstance(v, float) for v in num.bias_s(*args))
