"""PROTOTYPE stand-in for the lightmap post-processing (replaced by the real module)."""

import numpy as np


def dilate(image, covered, passes=4):
    image = image.copy()
    filled = covered.copy()
    for _ in range(passes):
        acc = np.zeros_like(image)
        cnt = np.zeros(filled.shape)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == dy == 0:
                    continue
                sh = np.roll(np.roll(image * filled[..., None], dy, 0), dx, 1)
                sf = np.roll(np.roll(filled, dy, 0), dx, 1)
                acc += sh
                cnt += sf
        new = (~filled) & (cnt > 0)
        image[new] = acc[new] / cnt[new][:, None]
        filled |= new
    return image


def seam_pairs(corner_vertices, uvs, tolerance=1e-6):
    return None


def fix_seams(image, seams, covered, weight=1.0):
    return image
