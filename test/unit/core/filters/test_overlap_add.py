"""Overlap-add convolutions sharing the input's transform: scipy's ``oaconvolve``, bit for bit."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import oaconvolve

from euc_ros.core.filters.overlap_add import oaconvolve_many

#: Seeds of the shared-transform convolution test, drawn once from default_rng(2026) (not picked).
OA_SEEDS = [int(s) for s in np.random.default_rng(2026).integers(0, 2**31, 4)]


@pytest.mark.parametrize("seed", OA_SEEDS)
def test_convolutions_sharing_the_inputs_transform_are_scipys_bit_for_bit(seed):
    # oaconvolve_many makes the input's blocks and transforms once for all kernels and does every step with a
    # kernel as scipy's oaconvolve does: each result must be oaconvolve's exactly (no tolerance), for the three
    # layouts the filters use (a reversed 1-D kernel; one row along axis 1; columns along axis 0) and for the
    # cases scipy does not split into blocks (a kernel as long as the input, short inputs)
    rng = np.random.default_rng(seed)
    for trial in range(30):
        n = int(rng.integers(2, 20000)) if trial % 4 else int(rng.integers(2, 300))
        w = int(rng.integers(1, 300)) | 1
        nk = int(rng.integers(1, 5))
        layout = trial % 3
        if layout == 0:
            x, ks, axes = rng.normal(size=n) * 1e3, [rng.normal(size=w)[::-1] for _ in range(nk)], 0
        elif layout == 1:
            x, ks, axes = rng.normal(size=(1, n)), [rng.normal(size=(1, w)) for _ in range(nk)], 1
        else:
            c = int(rng.integers(1, 6))
            x, ks, axes = rng.normal(size=(n, c)), [rng.normal(size=(w, 1)) for _ in range(nk)], 0
        got = list(oaconvolve_many(x, ks, axes))
        assert len(got) == nk
        for k, g in zip(ks, got):
            ref = oaconvolve(x, k, mode="full", axes=axes)
            assert g.shape == ref.shape and np.array_equal(g, ref), (n, w, layout)
    x = rng.normal(size=64)
    same = [rng.normal(size=64), rng.normal(size=64)]
    for k, g in zip(same, oaconvolve_many(x, same, 0)):
        assert np.array_equal(g, oaconvolve(x, k, mode="full", axes=0))
