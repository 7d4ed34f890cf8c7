"""matmul_serial: the same products as numpy's @, without waking a BLAS thread pool."""

import time

import numpy as np
import pytest
from conftest import process_cpu_per_wall_second

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
    """OpenBLAS threads a (40000 x 3) @ (3 x 3) product and its worker keeps a core busy for
    tens of milliseconds after the call; the same product through matmul_serial does not."""
    a = np.random.default_rng(1).random((40_000, 3))
    m = np.eye(3)
    time.sleep(0.3)  # let any worker from earlier tests go to sleep
    a @ m
    threaded = process_cpu_per_wall_second()
    if threaded < 1.5:
        pytest.skip(f"this numpy's BLAS does not spin after a threaded product ({threaded:.2f})")
    time.sleep(0.3)
    matmul_serial(a, m)
    matmul_serial(a, m[0])
    assert process_cpu_per_wall_second() < 1.3
