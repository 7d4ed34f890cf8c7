"""Ringing windows on synthetic suns never produce NaN or infinity (pure numpy)."""

import math

import numpy as np

from benchmarks import windows
from prt_addon.core.sh import analytic


def test_windows_never_produce_nan_or_inf_on_suns():
    """Every window of the core on a 1e6 sun (0.5 and 5 degrees) at orders 1 to 16: finite."""
    axis = np.array([0.3, 0.4, 0.866])
    for order in (1, 2, 4, 8, 16):
        for half in (0.5, 5.0):
            c = np.asarray(analytic.cap_coeffs(order, axis, math.radians(half), 1e6))
            c = np.repeat(c.reshape(-1, 1), 3, axis=1)
            c[0] += 0.05 * math.sqrt(4 * math.pi)
            for kind in ("NONE", "HANNING", "LANCZOS"):
                w = windows.window_weights(kind, order, None if kind == "NONE" else order)
                assert np.all(np.isfinite(windows.apply_window(c, w)))
            if order <= 8:
                res = windows.auto_window(c, "LAPLACIAN")
                assert np.all(np.isfinite(res.weights))
                assert res.min_value_after >= -1e-6 * c[0, 0]
