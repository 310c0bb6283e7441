"""Subnormal floats are flushed inside the block only, and the caller's state comes back."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.linalg import fpenv


def _subnormal_product() -> np.float32:
    return np.float32(1e-30) * np.float32(1e-10)  # 1e-40: below float32's 1.2e-38


@pytest.mark.skipif(fpenv._libm() is None, reason="flushing works on x86-64 glibc only")
def test_subnormals_are_flushed_in_the_block_and_restored_after_it_even_on_error():
    assert _subnormal_product() > 0  # gradual underflow outside
    with fpenv.flushing_subnormals():
        assert _subnormal_product() == 0
        assert np.float32(1e-30) * np.float32(1e-3) > 0  # normal results are untouched
    assert _subnormal_product() > 0
    with pytest.raises(KeyError), fpenv.flushing_subnormals():
        raise KeyError("inside")
    assert _subnormal_product() > 0
