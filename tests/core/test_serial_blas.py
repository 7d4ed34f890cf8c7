"""matmul_serial: the same products as numpy's @, without waking a BLAS thread pool."""

import numpy as np
import pytest
from helpers.threads import ticks_of_other_threads_after

from prt_addon.core.serial_blas import matmul_serial


def test_matmul_serial_is_the_matrix_product():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(40001, 3))
    for b in (rng.normal(size=(3, 3)), rng.normal(size=(3, 300)), rng.normal(size=3)):
        np.testing.assert_allclose(matmul_serial(a, b), a @ b, rtol=1e-13, atol=1e-13)
    wide = rng.normal(size=(700, 256))
    basis = rng.normal(size=(256, 16))
    out = rng.normal(size=(700, 16))
    expected = out + wide @ basis
    assert matmul_serial(wide, basis, out, accumulate=True) is out
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-12)
    assert matmul_serial(np.zeros((0, 3)), np.eye(3)).shape == (0, 3)


def test_matmul_serial_leaves_no_blas_thread_spinning():
    """OpenBLAS threads a (40000 x 3) @ (3 x 3) product, a (1 x 3) @ (3 x 4096) one (gemv) and
    an (8 x 512) @ (512 x 25) one, and its worker keeps a core busy for tens of milliseconds
    after the call; the same products through matmul_serial leave no other thread working."""
    rng = np.random.default_rng(1)
    a = rng.random((40_000, 3))
    m = np.eye(3)
    threaded = ticks_of_other_threads_after(lambda: a @ m)
    if threaded < 3:
        pytest.skip(f"this numpy's BLAS does not spin after a threaded product ({threaded} ticks)")
    wide = rng.random((3, 4096))
    tall = rng.random((512, 25))
    cases = {
        "(40000 x 3) @ (3 x 3)": lambda: matmul_serial(a, m),
        "(40000 x 3) @ (3,)": lambda: matmul_serial(a, m[0]),
        "(22 x 3) @ (3 x 4096), blocks of 21 rows and 1": lambda: matmul_serial(a[:22], wide),
        "(21 x 512) @ (512 x 25), accumulated": lambda: matmul_serial(
            rng.random((21, 512)), tall, np.zeros((21, 25)), accumulate=True
        ),
    }
    ticks = {name: ticks_of_other_threads_after(call) for name, call in cases.items()}
    assert all(t <= 1 for t in ticks.values()), ticks
