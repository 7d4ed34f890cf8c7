"""Matrix products that keep numpy's BLAS on the calling thread.

OpenBLAS runs a product on its own thread pool when it is large enough (gemm: m * n * k above
about 2^18, its default SMP threshold; gemv: m * n above about 9216), and its worker then spins
for tens of milliseconds after the call, holding a core. On the 2 cores the bake traces on, that
spinning worker takes CPU from the tracing threads: measured, the 2-thread bake was slower than
the 1-thread one, and one (31000 x 3) @ (3 x 3) product made the next 50 ms of single-threaded
numpy work use two cores. Products on the bake's path (set-up and slices) therefore go through
matmul_serial, split by rows below that size.
"""

import numpy as np

BLAS_SERIAL_MNK = 1 << 18


def matmul_serial(a, b, out=None, accumulate=False):
    """a @ b (or out += a @ b) for 2-D a and 2-D or 1-D b, in row blocks small enough for a
    serial BLAS call."""
    a = np.asarray(a)
    b = np.asarray(b)
    vector = b.ndim == 1
    b2 = b[:, None] if vector else b
    rows = max(1, BLAS_SERIAL_MNK // max(1, a.shape[1] * b2.shape[1]))
    if vector:  # gemv: threaded from m * n = 9216
        rows = max(1, min(rows, 9215 // max(1, a.shape[1])))
    if out is None:
        out = np.empty((a.shape[0], b2.shape[1]), dtype=np.result_type(a, b))
        accumulate = False
    out2 = out[:, None] if out.ndim == 1 else out
    for r0 in range(0, a.shape[0], rows):
        r1 = min(a.shape[0], r0 + rows)
        if accumulate:
            out2[r0:r1] += a[r0:r1] @ b2
        else:
            np.matmul(a[r0:r1], b2, out=out2[r0:r1])
    return out2[:, 0] if vector else out
