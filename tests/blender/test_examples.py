"""The user guide's script example (examples/bake_scene.py) runs under the bpy module."""

import os
import subprocess
import sys

from helpers.paths import ROOT


def test_bake_scene_example_runs(tmp_path):
    png = tmp_path / "view.png"
    run = subprocess.run(
        [sys.executable, os.path.join(ROOT, "examples", "bake_scene.py"), "--samples", "64", "--png", str(png)],
        capture_output=True,
        text=True,
        cwd=str(tmp_path),
        timeout=600,
    )
    assert "Traceback" not in run.stderr, run.stderr
    assert "Baked 2 object(s)" in run.stdout and "lighting turned  90 deg" in run.stdout, run.stdout
    assert png.is_file()
    assert png.stat().st_size > 1000
    assert run.returncode == 0, run.stdout + run.stderr
