"""Main job: project a bundled Blender HDRI into SH and report coefficients, error and timing.

Run through `bash scripts/demo.sh [--hdri forest] [--orders 2,3,4,6,8,12,16]`.
Errors are against the full-resolution image itself:
* radiance: relative RMS (solid-angle weighted) of the order-n reconstruction of the image;
* diffuse:  relative RMS of the unshadowed diffuse radiance E/pi = integral L max(0, n.w)/pi dw
  over 1024 Fibonacci normals, SH (order n) against a brute-force sum over every pixel.
The diffuse error is what unshadowed PRT shading sees; it falls much faster than the radiance
error because the clamped cosine's coefficients decay as l^-5/2.
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from prt_addon.core import analytic, directions, projection, sh  # noqa: E402


def load_bundled_hdri(name):
    import bpy

    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    path = os.path.join(folder, f"{name}.exr")
    image = bpy.data.images.load(path, check_existing=True)
    width, height = image.size
    pixels = np.empty(width * height * image.channels, np.float32)
    image.pixels.foreach_get(pixels)
    return path, pixels.reshape(height, width, image.channels)


def relative_rms(approx, exact, weights):
    return float(np.sqrt(np.sum(weights * (approx - exact) ** 2) / np.sum(weights * exact**2)))


def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hdri", default="forest", help="bundled studio-light HDRI name")
    parser.add_argument("--orders", default="2,3,4,6,8,12,16")
    parser.add_argument("--print-order", type=int, default=3, help="order whose coefficients are printed")
    args = parser.parse_args(argv)
    orders = [int(o) for o in args.orders.split(",")]

    path, pixels = load_bundled_hdri(args.hdri)
    height, width = pixels.shape[:2]
    rgb = pixels[:, :, :3].astype(np.float64)
    print(f"HDRI {path}: {width}x{height}, peak {rgb.max():.4g}, mean {rgb.mean():.4g}")

    dirs = projection.pixel_directions(height, width).reshape(-1, 3)
    weights = np.repeat(projection.pixel_solid_angles(height, width), width)
    image_lum = luminance(rgb.reshape(-1, 3))

    normals = directions.fibonacci_directions(1024)
    # Brute-force diffuse truth: every pixel as a small light of its solid angle.
    cosines = np.maximum(0.0, normals.astype(np.float32) @ dirs.T.astype(np.float32))
    diffuse_truth = luminance((cosines @ (rgb.reshape(-1, 3) * weights[:, None]).astype(np.float32)) / np.pi)

    print(f"\n{'order':>5} {'coeffs':>6} {'project ms':>10} {'radiance err':>12} {'diffuse err':>11}")
    printed = None
    for order in orders:
        start = time.perf_counter()
        coeffs, report = projection.project_equirect(pixels, order)
        seconds = time.perf_counter() - start
        recon = luminance(sh.evaluate(coeffs, dirs))
        radiance_error = relative_rms(recon, image_lum, weights)
        diffuse = luminance(sh.evaluate(sh.convolve_zonal(coeffs, analytic.clamped_cosine_zonal(order)), normals))
        diffuse_error = relative_rms(diffuse, diffuse_truth, np.ones_like(diffuse))
        print(f"{order:>5} {order * order:>6} {seconds * 1e3:>10.1f} {radiance_error:>11.1%} {diffuse_error:>10.2%}")
        if order == args.print_order:
            printed = coeffs
    print(f"\npixel check: {report.summary()}")
    if printed is not None:
        print(f"\nRGB coefficients at order {args.print_order} (index i = l(l+1)+m, no Condon-Shortley phase, Z up):")
        for i, (r, g, b) in enumerate(printed):
            l = int(np.sqrt(i))
            print(f"  i={i:<3} l={l} m={i - l * (l + 1):>2}: {r:12.6f} {g:12.6f} {b:12.6f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
