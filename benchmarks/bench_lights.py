"""Light extraction benchmark: time at 1024x512 and 4096x2048, and what Blender's HDRIs give.

Run: .venv/bin/python benchmarks/bench_lights.py
Synthetic skies (uniform 1 plus a 0.5 degree sun of radiance 3e4) are timed at both sizes, with
the automatic threshold, plus a stress case where 30 % of the texels are bright (random noise and
a fixed threshold: many regions). If bpy is importable, each of Blender's bundled world HDRIs
(studiolights/world, read with Image.pixels, row 0 at the bottom as the projection expects) is
extracted with the automatic threshold and the lights are listed.
"""

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from prt_addon.core.lights import extraction as lights
from prt_addon.core.sh import projection


def timed(fn, repeats):
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times)), 1e3 * float(np.min(times))


def sunny_sky(height, width, elevation_deg=35.0, radius_deg=0.5, radiance=3e4):
    directions = projection.pixel_directions(height, width)
    e = np.radians(elevation_deg)
    sun = np.array([np.cos(e) * 0.6, np.cos(e) * 0.8, np.sin(e)])
    inside = directions @ sun >= np.cos(np.radians(radius_deg))
    image = np.ones((height, width, 3), np.float32)
    image[inside] = radiance
    return image


def world_power(pixels):
    lum = lights._luminance(pixels[:, :, :3])
    solid = projection.pixel_solid_angles(*lum.shape)
    return float(lum.sum(axis=1) @ solid)


def synthetic():
    print("Extraction time, float32 RGB (median / best of the runs, ms)")
    print(f"{'image':>34} {'median':>8} {'best':>8} {'lights':>6} {'bright texels':>13}")
    rng = np.random.default_rng(0)
    for height, repeats in ((512, 30), (2048, 5)):
        width = 2 * height
        sky = sunny_sky(height, width)
        noise = rng.random((height, width, 3)).astype(np.float32)
        cases = (
            (f"{width}x{height} sky + 0.5 deg sun", sky, {}),
            (f"{width}x{height} 30 % bright (noise)", noise, {"threshold": 0.7 * 0.7, "min_share": 0.0}),
        )
        for name, image, kwargs in cases:
            median, best = timed(lambda: lights.extract_lights(image, **kwargs), repeats)
            _, found = lights.extract_lights(image, **kwargs)
            threshold = kwargs.get("threshold", lights.auto_threshold(image))
            bright = int((lights._luminance(image) > threshold).sum())
            print(f"{name:>34} {median:>8.1f} {best:>8.1f} {len(found):>6} {bright:>13}")


def bundled_worlds():
    try:
        import bpy
    except ImportError:
        print("\nbpy not importable: Blender's HDRIs skipped")
        return
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    print(f"\nBlender {bpy.app.version_string} world HDRIs (automatic threshold, max 4 lights)")
    print(
        f"{'world':>10} {'size':>9} {'peak':>8} {'T':>7} {'by':>7} {'lights':>6} "
        f"{'share':>6} {'elev.':>6} {'angle':>6} {'ms':>6}  each light: share % / angle deg"
    )
    for name in sorted(f[:-4] for f in os.listdir(folder) if f.endswith(".exr")):
        image = bpy.data.images.load(os.path.join(folder, f"{name}.exr"))
        width, height = image.size
        buffer = np.empty(width * height * image.channels, dtype=np.float32)
        image.pixels.foreach_get(buffer)
        bpy.data.images.remove(image)
        pixels = buffer.reshape(height, width, -1)[:, :, :3]
        threshold = lights.auto_threshold(pixels)
        mean = world_power(pixels) / (4.0 * np.pi)
        rule = "mean" if threshold <= lights.MEAN_FACTOR * mean * (1 + 1e-9) else "compact"
        median, _ = timed(lambda: lights.extract_lights(pixels), 10)
        _, found = lights.extract_lights(pixels)
        total = world_power(pixels)
        share = sum(light.luminance for light in found) / total
        strongest = found[0] if found else None
        elevation = np.degrees(np.arcsin(strongest.direction[2])) if strongest else float("nan")
        angle = np.degrees(strongest.angle) if strongest else float("nan")
        peak = float(lights._luminance(pixels).max())
        each = " ".join(f"{100 * light.luminance / total:.1f}/{np.degrees(light.angle):.2f}" for light in found)
        print(
            f"{name:>10} {width}x{height:<4} {peak:>8.0f} {threshold:>7.2f} {rule:>7} "
            f"{len(found):>6} {100 * share:>5.1f}% {elevation:>6.1f} {angle:>6.2f} "
            f"{median:>6.1f}  {each}"
        )


if __name__ == "__main__":
    synthetic()
    bundled_worlds()
