"""The SH basis table of docs/export.md (bands 0-2) is the project's basis."""

import numpy as np


def test_basis_table_in_docs():
    """The band 0-2 table of docs/export.md is the project's basis."""
    from prt_addon import api

    d = np.array([[0.36, 0.48, 0.8]])
    x, y, z = d[0]
    table = [
        0.282095,
        0.488603 * y,
        0.488603 * z,
        0.488603 * x,
        1.092548 * x * y,
        1.092548 * y * z,
        0.315392 * (3 * z * z - 1),
        1.092548 * x * z,
        0.546274 * (x * x - y * y),
    ]
    assert np.allclose(api.sh_basis(d, 3)[0], table, atol=2e-6)
