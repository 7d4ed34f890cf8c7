"""Build the extension zips, one per platform, with the embreex wheels they need.

    .venv/bin/python scripts/build_extension.py [--output-dir build/dist] [--platforms linux-x64,...]
                                                [--no-wheels]

The wheels are downloaded from the package index at build time (never committed) for CPython
3.11 (Blender 4.2 to 5.0) and 3.13 (Blender 5.1 and later); numpy is never bundled (Blender ships
it). The source is staged in build/stage with a manifest that lists the platforms and wheels,
then Blender's own extension builder (blender_ext.py from the bpy package, the same code as
`blender --command extension build`) validates it and writes one zip per platform.
"""

import argparse
import glob
import os
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EMBREEX = "embreex==4.4.0.post1"
PYTHON_VERSIONS = ("311", "313")
# Blender platform -> pip platform tag of the embreex wheels.
PLATFORM_TAGS = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_13_0_arm64",
    "macos-x64": "macosx_13_0_x86_64",
}
SOURCES = ("__init__.py", "blender_manifest.toml", "prt_addon")


def blender_ext_script():
    import bpy  # only to find the builder that ships inside the bpy package

    scripts = bpy.utils.system_resource("SCRIPTS")
    path = os.path.join(scripts, "addons_core", "bl_pkg", "cli", "blender_ext.py")
    if not os.path.isfile(path):
        raise SystemExit(f"Blender's extension builder was not found at {path}")
    return path


def download_wheels(platforms, wheel_dir):
    os.makedirs(wheel_dir, exist_ok=True)
    for platform in platforms:
        for python in PYTHON_VERSIONS:
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "pip",
                    "download",
                    "--quiet",
                    "--no-deps",
                    "--only-binary=:all:",
                    "--python-version",
                    python,
                    "--platform",
                    PLATFORM_TAGS[platform],
                    "--dest",
                    wheel_dir,
                    EMBREEX,
                ],
                check=True,
            )
    return sorted(os.path.basename(p) for p in glob.glob(os.path.join(wheel_dir, "*.whl")))


def stage(stage_dir, platforms, wheels):
    shutil.rmtree(stage_dir, ignore_errors=True)
    os.makedirs(stage_dir)
    for name in SOURCES:
        source = os.path.join(ROOT, name)
        if os.path.isdir(source):
            shutil.copytree(
                source, os.path.join(stage_dir, name), ignore=shutil.ignore_patterns("__pycache__", "*.pyc")
            )
        else:
            shutil.copy2(source, stage_dir)
    manifest_path = os.path.join(stage_dir, "blender_manifest.toml")
    with open(manifest_path, encoding="utf-8") as f:
        manifest = f.read()
    listed = "platforms = [%s]\n" % ", ".join(f'"{p}"' for p in platforms)
    if wheels:  # the manifest allows no empty values
        listed += "wheels = [\n%s]\n" % "".join(f'  "./wheels/{w}",\n' for w in wheels)
    listed += "\n"
    # Top-level keys must come before the first [table] of the TOML file.
    first_table = manifest.index("\n[") + 1
    with open(manifest_path, "w", encoding="utf-8") as f:
        f.write(manifest[:first_table] + listed + manifest[first_table:])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", default=os.path.join(ROOT, "build", "dist"))
    parser.add_argument("--platforms", default=",".join(PLATFORM_TAGS))
    parser.add_argument(
        "--no-wheels",
        action="store_true",
        help="bundle no embreex wheel (what a platform without one gets: the BVH tree fallback); nothing is downloaded",
    )
    args = parser.parse_args(argv)
    platforms = [p for p in args.platforms.split(",") if p]
    unknown = set(platforms) - set(PLATFORM_TAGS)
    if unknown:
        raise SystemExit(f"unknown platforms {sorted(unknown)}; known: {sorted(PLATFORM_TAGS)}")

    stage_dir = os.path.join(ROOT, "build", "stage")
    wheel_dir = os.path.join(ROOT, "build", "wheels")
    shutil.rmtree(wheel_dir, ignore_errors=True)
    if args.no_wheels:
        os.makedirs(wheel_dir)
        wheels = []
    else:
        wheels = download_wheels(platforms, wheel_dir)
    stage(stage_dir, platforms, wheels)
    shutil.copytree(wheel_dir, os.path.join(stage_dir, "wheels"))
    os.makedirs(args.output_dir, exist_ok=True)
    builder = blender_ext_script()
    subprocess.run(
        [
            sys.executable,
            builder,
            "build",
            "--source-dir",
            stage_dir,
            "--output-dir",
            args.output_dir,
            "--split-platforms",
        ],
        check=True,
    )
    zips = sorted(glob.glob(os.path.join(args.output_dir, "*.zip")))
    for path in zips:
        print(f"{os.path.getsize(path) / 1e6:8.1f} MB  {path}")
    return zips


if __name__ == "__main__":
    main()
