"""GGX-prefiltered cube maps of an equirectangular environment (specular image-based lighting).

The cube frame is WebGL's (OpenGL's) cube-map convention: a direction r selects the face of its
largest component and the face coordinates (s, t) of the table below; face k's texel (row j,
column i) of an N x N face has s = (2 i + 1) / N - 1 and t = (2 j + 1) / N - 1 at its centre, and
row j = 0 is the first row in texture memory (t = -1).

    face     direction at (s, t)
    0  +X    ( 1, -t, -s)
    1  -X    (-1, -t,  s)
    2  +Y    ( s,  1,  t)
    3  -Y    ( s, -1, -t)
    4  +Z    ( s, -t,  1)
    5  -Z    (-s, -t, -1)

Mip k of a cube of size N0 = 2^K holds the radiance prefiltered with the GGX lobe of
alpha_k = 2^k / N0 (alpha_0 = 0: mip 0 is the radiance itself; alpha_K = 1), Babylon.js's mapping
of roughness to mips (alpha = roughness^2, lod = log2(N0 alpha)). The prefilter assumes N = V = R
and weights each source texel by max(n.l, 0) D(h) dOmega, normalised (the usual split-sum
prefilter, computed as a deterministic sum over texels instead of importance samples): with
c = n.l, n.h = sqrt((1 + c) / 2), so D is a function of c alone,
D = alpha^2 / (pi (alpha^2 + (1 - c) (1 - alpha^2) / 2)^2). The source of mip k is the radiance
cube reduced to min(N0, max(2 N_k, 32)) texels (2x2 solid-angle-weighted means).

Cost: the output texels of 1/48 of the sphere (0 <= s <= t on face +X) against every source
texel, in chunks of at most CHUNK_ELEMENTS weights (float32); every other output texel comes
from the same weights, since the texel grid is symmetric under the cube's 48 signed permutations
and the weight depends only on n.l: about 6 N_k^2 x 6 S_k^2 / 48 weights per mip and a matrix
product with 48 x 3 columns, dominated by mip 1 (N0 = 128: 528 x 98304 weights).
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

from ..sh import resample

# Face k's direction at (s, t, 1): FACE_MATRICES[k] @ (s, t, 1) (see the table above).
FACE_MATRICES = np.array(
    [
        [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],
        [[0, 0, -1], [0, -1, 0], [1, 0, 0]],
        [[1, 0, 0], [0, 0, 1], [0, 1, 0]],
        [[1, 0, 0], [0, 0, -1], [0, -1, 0]],
        [[1, 0, 0], [0, -1, 0], [0, 0, 1]],
        [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],
    ],
    dtype=np.float64,
)
FACE_NAMES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
CHUNK_ELEMENTS = 1 << 22  # weights per chunk (16 MB in float32; a few such arrays at a time)
MIN_SOURCE = 32  # the coarse mips are summed over at least this source resolution
TINY = 1e-30  # source values below this (times the texel's solid angle) count as 0


MAX_SIZE = 256  # the prefilter's cost grows as size^4: 256 takes half a minute (docs/export.md)


def check_size(size: int) -> int:
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1 or size & (size - 1):
        raise ValueError(f"the cube map size must be a power of two, got {size!r}")
    if size > MAX_SIZE:
        raise ValueError(f"the cube map size must be at most {MAX_SIZE}, got {size}")
    return int(size)


def face_coordinates(size: int) -> np.ndarray:
    """(size,) s (or t) at the texel centres: (2 i + 1) / size - 1."""
    return (2.0 * np.arange(size, dtype=np.float64) + 1.0) / size - 1.0


def face_directions(size: int) -> np.ndarray:
    """(6, size, size, 3) unit directions at the texel centres, [face, row j (t), column i (s)]."""
    c = face_coordinates(check_size(size))
    t, s = np.meshgrid(c, c, indexing="ij")
    local = np.stack([s, t, np.ones_like(s)], axis=-1)  # (N, N, 3)
    d = np.einsum("kab,jib->kjia", FACE_MATRICES, local)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def direction_to_texel(directions: npt.ArrayLike, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(face, row, column) int arrays of the texels that directions (..., 3) fall in."""
    d = np.asarray(directions, dtype=np.float64)
    axis = np.argmax(np.abs(d), axis=-1)
    major = np.take_along_axis(d, axis[..., None], axis=-1)[..., 0]
    face = 2 * axis + (major < 0)
    # (s, t, 1) = M^T d / |major| for the face's matrix M (a signed permutation: M^-1 = M^T).
    local = np.einsum("...ba,...b->...a", FACE_MATRICES[face], d) / np.abs(major)[..., None]
    column = np.clip(np.floor((local[..., 0] + 1.0) * 0.5 * size), 0, size - 1).astype(np.int64)
    row = np.clip(np.floor((local[..., 1] + 1.0) * 0.5 * size), 0, size - 1).astype(np.int64)
    return face, row, column


def texel_solid_angles(size: int) -> np.ndarray:
    """(size, size) exact solid angle of each texel of a face (the same on every face); the six
    faces sum to 4 pi."""
    edges = np.linspace(-1.0, 1.0, check_size(size) + 1)
    x, y = np.meshgrid(edges, edges, indexing="ij")
    a = np.arctan2(x * y, np.sqrt(x * x + y * y + 1.0))
    return a[1:, 1:] - a[:-1, 1:] - a[1:, :-1] + a[:-1, :-1]


def equirect_lookup(pixels: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(..., 3) the pixel of an (H, W, 3) equirect image (Blender's convention, row 0 at the
    bottom, core.sh.projection) that each direction (..., 3) falls in (the image taken as constant
    over each pixel, as the projection takes it)."""
    height, width = pixels.shape[:2]
    x, y, z = directions[..., 0], directions[..., 1], directions[..., 2]
    u = -np.arctan2(y, x) / (2.0 * np.pi) + 0.5
    v = np.arctan2(z, np.hypot(x, y)) / np.pi + 0.5
    column = np.floor(u * width).astype(np.int64) % width
    row = np.clip(np.floor(v * height).astype(np.int64), 0, height - 1)
    return pixels[row, column]


def cube_from_function(function, size: int, supersample: int = 2) -> np.ndarray:
    """(6, size, size, C) mean of function(directions (..., 3)) -> (..., C) over supersample^2
    points of each texel (evenly spread in face coordinates)."""
    size = check_size(size)
    fine = face_directions(size * supersample)  # a texel's sub-points are an ss x ss block
    out: np.ndarray | None = None
    for k in range(6):
        values = np.asarray(function(fine[k]), dtype=np.float64)
        values = values.reshape(size, supersample, size, supersample, -1).mean(axis=(1, 3))
        if out is None:
            out = np.empty((6, *values.shape))
        out[k] = values
    assert out is not None  # (six faces: set by the first)
    return out


def radiance_cube(pixels: npt.ArrayLike, size: int, to_image: npt.ArrayLike | None = None, supersample: int = 2):
    """(6, size, size, 3) float64 radiance cube of an equirect image (row 0 at the bottom).

    to_image: 3x3 matrix taking a cube-frame direction to the image's frame (None: identity).
    Images wider than 4 size are first reduced by exact area averaging (core.sh.resample) to
    4 size x 2 size, so the supersample^2 point lookups of a texel do not alias; NaN, infinite
    and negative values are repaired as the projection repairs them."""
    size = check_size(size)
    rgb = np.asarray(pixels)
    height, width = rgb.shape[:2]
    target_w, target_h = min(width, 4 * size), min(height, 2 * size)
    rgb, _report, _energy = resample.reduce_equirect(rgb, target_h, target_w)
    m = np.eye(3) if to_image is None else np.asarray(to_image, dtype=np.float64)
    return cube_from_function(lambda d: equirect_lookup(rgb, d @ m.T), size, supersample)


def reduce_cube(cube: np.ndarray) -> np.ndarray:
    """(6, N/2, N/2, C): each texel the solid-angle-weighted mean of its 2x2 children."""
    n = cube.shape[1]
    omega = texel_solid_angles(n)[None, :, :, None]
    weighted = (cube * omega).reshape(6, n // 2, 2, n // 2, 2, -1).sum(axis=(2, 4))
    return weighted / omega.reshape(1, n // 2, 2, n // 2, 2, 1).sum(axis=(2, 4))


def babylon_alphas(size: int) -> np.ndarray:
    """GGX alpha of each mip of a full chain of size N0 down to 1: 0, 2/N0, 4/N0, ..., 1."""
    size = check_size(size)
    levels = size.bit_length()  # log2(size) + 1
    alphas = 2.0 ** np.arange(levels) / size
    alphas[0] = 0.0
    return alphas


def ggx_weight(cosine: np.ndarray, alpha: float) -> np.ndarray:
    """max(n.l, 0) D(h) (N = V, h the half vector) up to the constant alpha^2 / pi, float32;
    computed in place in `cosine` (float32), which it returns."""
    k = 0.5 * (1.0 - alpha * alpha)
    q = np.multiply(cosine, np.float32(-k))
    q += np.float32(alpha * alpha + k)  # alpha^2 + (1 - c) (1 - alpha^2) / 2
    np.square(q, out=q)
    np.maximum(cosine, np.float32(0.0), out=cosine)
    cosine /= q
    return cosine


def cube_symmetries() -> np.ndarray:
    """(48, 3, 3) the signed permutation matrices: the rotations and reflections of the cube,
    each of which maps the texel centres of any N x N cube onto themselves."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[range(3), perm] = signs
            out.append(m)
    return np.array(out)


def _flat_index(directions, size):
    face, row, column = direction_to_texel(directions, size)
    return (face * size + row) * size + column


def symmetry_indices(g: np.ndarray, size: int) -> np.ndarray:
    """(6 size^2,) flat index of the texel at g d for every texel centre d (g a cube symmetry),
    by integer arithmetic: g M_f (s, t, 1) = M_f' (s', t', 1) with (s', t') a signed swap of
    (s, t), and s -> -s is column i -> size - 1 - i."""
    out = np.empty((6, size, size), dtype=np.int64)
    j, i = np.indices((size, size))
    for f in range(6):
        axis = g @ FACE_MATRICES[f][:, 2]  # the face's normal, moved
        f2 = int(_flat_index(axis[None, :], 1)[0])
        p = FACE_MATRICES[f2].T @ g @ FACE_MATRICES[f]  # (s, t, 1) -> (s', t', 1)
        s_src = np.where(p[0, 0] != 0, i, j)  # which of (i, j) becomes the new column
        t_src = np.where(p[1, 0] != 0, i, j)
        s_sign, t_sign = p[0, 0] + p[0, 1], p[1, 0] + p[1, 1]
        column = np.where(s_sign > 0, s_src, size - 1 - s_src)
        row = np.where(t_sign > 0, t_src, size - 1 - t_src)
        out[f] = (f2 * size + row) * size + column
    return out.ravel()


def fundamental_texels(size: int) -> np.ndarray:
    """Flat indices (into face +X) of the texels with 0 <= s <= t: 1/48 of the sphere, whose
    images under the 48 symmetries cover every texel."""
    c = face_coordinates(size)
    t, s = np.meshgrid(c, c, indexing="ij")
    keep = (s >= -1e-12) & (t >= s - 1e-12)
    return np.flatnonzero(keep.ravel())


def prefilter_level(source: np.ndarray, size: int, alpha: float) -> np.ndarray:
    """(6, size, size, C) GGX prefilter (N = V = R) of a source cube (6, S, S, C) at alpha.

    The weights are computed for the fundamental texels only; since the weight depends on n.l
    alone, the output at G n (G one of the 48 cube symmetries) is the same weights applied to the
    source seen through G: sum_s w(n . d_s) L(G d_s)."""
    size = check_size(size)
    s = source.shape[1]
    channels = source.shape[-1]
    src_dirs = face_directions(s).reshape(-1, 3)
    omega = np.tile(texel_solid_angles(s).ravel(), 6).astype(np.float32)
    flat = (source.reshape(-1, channels) * omega[:, None]).astype(np.float32)  # omega is symmetric too
    flat[np.abs(flat) < TINY] = 0.0  # float32 subnormals make the matrix products 100 times slower
    groups = cube_symmetries()
    # Columns g * C + c: the source through symmetry g.
    permuted = np.concatenate([flat[symmetry_indices(g, s)] for g in groups], axis=1)
    src_dirs = src_dirs.astype(np.float32)
    base = face_directions(size)[0].reshape(-1, 3)[fundamental_texels(size)]
    targets = np.stack([_flat_index(base @ g.T, size) for g in groups])  # (48, fundamental)
    result = np.empty((base.shape[0], len(groups) * channels))
    rows = max(1, CHUNK_ELEMENTS // src_dirs.shape[0])
    for start in range(0, base.shape[0], rows):
        cosine = base[start : start + rows].astype(np.float32) @ src_dirs.T
        w = ggx_weight(cosine, alpha)
        total = w @ omega
        result[start : start + rows] = (w @ permuted) / total[:, None]
    out = np.empty((6 * size * size, channels))
    for k in range(len(groups)):
        out[targets[k]] = result[:, k * channels : (k + 1) * channels]
    return out.reshape(6, size, size, channels)


def source_size(base: int, size: int) -> int:
    """The source resolution a mip of `size` is summed over: min(base, max(2 size, MIN_SOURCE))."""
    return min(base, max(2 * size, MIN_SOURCE))


def prefilter_mips(cube: np.ndarray, alphas: npt.ArrayLike | None = None) -> list[np.ndarray]:
    """The mips [(6, N0 >> k, N0 >> k, C)] of a radiance cube (6, N0, N0, C): mip 0 is the cube,
    mip k the GGX prefilter at alphas[k] (default babylon_alphas(N0): the full chain to 1 texel)."""
    base = check_size(cube.shape[1])
    alphas = babylon_alphas(base) if alphas is None else np.asarray(alphas, dtype=np.float64)
    reduced = {base: np.asarray(cube, dtype=np.float64)}
    while min(reduced) > 1:
        reduced[min(reduced) // 2] = reduce_cube(reduced[min(reduced)])
    mips = []
    for k, alpha in enumerate(alphas):
        size = base >> k
        if size < 1:
            raise ValueError(f"{len(alphas)} mips do not fit a cube of size {base}")
        if alpha == 0.0:
            mips.append(reduced[size].copy())
        else:
            mips.append(prefilter_level(reduced[source_size(base, size)], size, float(alpha)))
    return mips
