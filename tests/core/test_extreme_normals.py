"""NaN and zero normals give zero transfer (the core's quadrature, no Blender)."""

import math

import numpy as np
import pytest


def test_nan_and_zero_normals_give_zero_transfer():
    from prt_addon.core.sh.directions import make_directions
    from prt_addon.core.transfer import quadrature as transfer

    normals = np.array([[0, 0, 0], [np.nan, 0, 1], [np.inf, 0, 0], [0, 0, 1e-30], [0, 0, 1]])
    res = transfer.compute_transfer(np.zeros((5, 3)), normals, make_directions("FIBONACCI", 64, 0), 4)
    assert np.all(np.isfinite(res.coeffs))
    assert np.all(np.isfinite(res.error))
    assert not res.coeffs[:4].any()
    assert res.coeffs[4, 0] == pytest.approx(0.5 / math.sqrt(math.pi), rel=1e-2)
