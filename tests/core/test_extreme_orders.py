"""The largest order without Blender: the basis and the projection stay finite."""

import numpy as np

from prt_addon.core.sh import basis as sh


def test_basis_and_projection_at_the_largest_order_are_finite():
    """The order the bake offers at most (16) and far beyond: finite basis at awkward directions."""
    d = np.array([[0, 0, 1], [0, 0, -1], [1e-12, 0, 1], [3, 4, 0], [0, 0, 1e-300], [1e300, 1e300, 0]])
    y = sh.sh_basis(d, 101)
    assert np.all(np.isfinite(y))
    np.testing.assert_array_equal(y[4], y[0])  # tiny and huge lengths normalise exactly
    np.testing.assert_allclose(y[5], sh.sh_basis(np.array([[1.0, 1.0, 0.0]]), 101)[0], atol=1e-12)
