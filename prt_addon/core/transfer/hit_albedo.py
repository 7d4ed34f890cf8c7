"""The albedo where a bounce ray hits a textured triangle: its image looked up at the hit's UV."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .image_sampling import sample_image


class HitAlbedo:
    """Textured triangles of a hit sink's soup: per triangle its corners' UVs and the image it
    shows (linear RGB, already times its colour and clamped to [0, 1]; -1: not textured).

    Called with hit triangles and their barycentrics (b1, b2: the weights of corners 1 and 2, as
    core.transfer.bounce_hits.hit_barycentrics gives them divided by det), it returns which hits
    are textured and their albedo, the image looked up as its node samples it
    (image_sampling.sample_image) at uv = (1 - b1 - b2) uv_0 + b1 uv_1 + b2 uv_2.
    """

    def __init__(self, n_triangles: int) -> None:
        self.image_of = np.full(n_triangles, -1, np.int32)
        self.uvs = np.zeros((n_triangles, 3, 2), np.float32)
        self.images: list[np.ndarray] = []
        self.sampling: list[tuple[int, int]] = []  # per image: (interpolation, extension), image_sampling' numbers
        self._keys: dict[object, int] = {}

    def add(
        self,
        triangles: npt.ArrayLike,
        uvs: npt.ArrayLike,
        image: npt.ArrayLike,
        key: object = None,
        sampling: tuple[int, int] = (0, 0),
    ) -> None:
        """Triangles (indices into the soup) showing `image` (H, W, 3), row 0 at v = 0, with
        their corners' UVs (k, 3, 2), sampled as `sampling` (interpolation, extension) says;
        triangles added with the same key (not None) share one copy."""
        index = np.asarray(triangles, dtype=np.int64)
        self.uvs[index] = np.asarray(uvs, dtype=np.float32).reshape(-1, 3, 2)
        if key is None or key not in self._keys:
            if key is not None:
                self._keys[key] = len(self.images)
            self.images.append(np.clip(np.asarray(image, dtype=np.float32), 0.0, 1.0))
            self.sampling.append((int(sampling[0]), int(sampling[1])))
        self.image_of[index] = self._keys[key] if key is not None else len(self.images) - 1

    def flip(self, triangles: npt.ArrayLike) -> None:
        """Triangles the sink stores as (a, c, b): their UVs follow."""
        index = np.asarray(triangles, dtype=np.int64)
        self.uvs[index] = self.uvs[index][:, [0, 2, 1]]

    @property
    def textured(self) -> bool:
        return bool(self.images)

    def __call__(self, prims: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(which (m,) bool, (which.sum(), 3) float32 albedo) of the hits on triangles `prims`."""
        images = self.image_of[prims]
        which = images >= 0
        out = np.empty((int(which.sum()), 3), np.float32)
        if not len(out):
            return which, out
        tri, image_ids = prims[which], images[which]
        w1, w2 = b1[which][:, None], b2[which][:, None]
        corners = self.uvs[tri]
        uv = corners[:, 0] * (1.0 - w1 - w2) + corners[:, 1] * w1 + corners[:, 2] * w2
        if len(self.images) == 1:
            out[:] = sample_image(self.images[0], uv, np.float32, *self.sampling[0])
            return which, out
        for k in np.unique(image_ids):
            here = image_ids == k
            out[here] = sample_image(self.images[k], uv[here], np.float32, *self.sampling[k])
        return which, out
