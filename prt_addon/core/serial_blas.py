"""Matrix products that keep numpy's BLAS on the calling thread.

OpenBLAS runs a product on its own thread pool when it is large enough (gemm: m * n * k above
about 2^18, its default SMP threshold; gemv: m * n above about 9216), and its worker then spins
for tens of milliseconds after the call, holding a core. On the 2 cores the bake traces on, that
spinning worker takes CPU from the tracing threads: measured, the 2-thread bake was slower than
the 1-thread one, and one (31000 x 3) @ (3 x 3) product made the next 50 ms of single-threaded
numpy work use two cores. Products on the bake's path (set-up and slices) therefore go through
matmul_serial, split by rows below that size.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

BLAS_SERIAL_MNK = 1 << 18  # gemm: threaded above m * n * k = 2^18
BLAS_SERIAL_GEMV = 9216  # gemv: threaded from m * n = 9216


def matmul_serial(
    a: npt.ArrayLike, b: npt.ArrayLike, out: np.ndarray | None = None, accumulate: bool = False
) -> np.ndarray:
    """a @ b (or out += a @ b) for 2-D a and 2-D or 1-D b, in blocks small enough for a serial
    BLAS call. Returns out (for a 1-D b, a 1-D view of it)."""
    a = np.asarray(a)
    b = np.asarray(b)
    if a.ndim != 2 or b.ndim not in (1, 2):
        raise ValueError(f"matmul_serial needs a 2-D a and a 1-D or 2-D b, got {a.shape} and {b.shape}")
    vector = b.ndim == 1
    b2 = b[:, None] if vector else b
    k, n = b2.shape
    rows = max(1, BLAS_SERIAL_MNK // max(1, k * n))
    if vector:
        rows = max(1, min(rows, (BLAS_SERIAL_GEMV - 1) // max(1, k)))
    if out is None:
        out = np.empty((a.shape[0], n), dtype=np.result_type(a, b))
        accumulate = False
    out2 = out[:, None] if out.ndim == 1 else out
    for r0 in range(0, a.shape[0], rows):
        r1 = min(a.shape[0], r0 + rows)
        if r1 - r0 == 1 and k * n >= BLAS_SERIAL_GEMV:
            # numpy computes a one-row product with gemv, threaded at this size: einsum instead.
            product = np.einsum("ij,jk->ik", a[r0:r1], b2)
            if accumulate:
                out2[r0:r1] += product
            else:
                out2[r0:r1] = product
        elif accumulate:
            out2[r0:r1] += a[r0:r1] @ b2
        else:
            np.matmul(a[r0:r1], b2, out=out2[r0:r1])
    return out2[:, 0] if vector else out
