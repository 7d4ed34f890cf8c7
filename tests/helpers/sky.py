"""Synthetic skies in pure numpy: equirect images with discs, solid angles, rotations."""

import numpy as np

from prt_addon.core.sh.projection import pixel_directions

HEIGHT, WIDTH = 512, 1024


def unit(azimuth_deg, elevation_deg):
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def disc_fractions(height, width, centre, radius, sub=32):
    """(H, W) fraction of every texel covered by the cap: 1 or 0 away from its edge, and
    sub x sub samples uniform in (z, phi), i.e. in solid angle, for texels near the edge."""
    directions = pixel_directions(height, width)
    distance = np.arccos(np.clip(directions @ centre, -1.0, 1.0))
    margin = 1.5 * max(np.pi / height, 2.0 * np.pi / width)
    fraction = (distance < radius - margin).astype(np.float64)
    rows, cols = np.nonzero(np.abs(distance - radius) <= margin)
    z_edges = np.sin((np.arange(height + 1) / height - 0.5) * np.pi)
    phi_step = 2.0 * np.pi / width
    t = (np.arange(sub) + 0.5) / sub
    for start in range(0, len(rows), 2048):
        r, c = rows[start : start + 2048], cols[start : start + 2048]
        z = z_edges[r, None, None] + (z_edges[r + 1] - z_edges[r])[:, None, None] * t[:, None]
        phi = np.pi - phi_step * (c[:, None, None] + t[None, :])
        z, phi = np.broadcast_arrays(z, phi)
        s = np.sqrt(1.0 - z * z)
        inside = s * np.cos(phi) * centre[0] + s * np.sin(phi) * centre[1] + z * centre[2] >= np.cos(radius)
        fraction[r, c] = inside.mean(axis=(1, 2))
    return fraction


def sky_with_discs(discs, sky=1.0, height=HEIGHT, width=WIDTH):
    """float32 RGB image: uniform `sky` plus caps (centre, radius, radiance) replacing it."""
    image = np.full((height, width, 3), sky, dtype=np.float64)
    for centre, radius, radiance in discs:
        fraction = disc_fractions(height, width, centre, radius)
        image += fraction[:, :, None] * (np.asarray(radiance, dtype=np.float64) - sky)
    return image.astype(np.float32)


def cap_solid_angle(radius):
    return 2.0 * np.pi * (1.0 - np.cos(radius))


SUN = unit(30.0, 20.0)
RADIUS = np.radians(2.0)


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class HalfPlane:
    """Occluder: the half-plane z = 1, y > 0 (the raytrace protocol, in numpy)."""

    def occluded(self, origins, directions):
        assert origins.dtype == np.float32
        assert directions.dtype == np.float32
        o, d = origins.astype(np.float64), directions.astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (1.0 - o[:, 2]) / d[:, 2]
        return (d[:, 2] > 0) & (t > 0) & (o[:, 1] + t * d[:, 1] > 0)
