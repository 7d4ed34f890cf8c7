"""End to end, as a user would: build the linux-x64 zip, install it with Blender's own extension
installer into a fresh user directory, enable, use, disable and remove it."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# The suite itself runs on the bpy of requirements-dev.txt; the install test also runs on the
# other supported Blender versions, each in its own venv made by scripts/bpy_venv.sh.
OTHER_BPY_VERSIONS = ["4.2.23", "4.5.15"]


def python_for(version):
    if version == "current":
        return sys.executable
    made = subprocess.run(["bash", os.path.join(ROOT, "scripts", "bpy_venv.sh"), version], capture_output=True, text=True)
    assert made.returncode == 0, made.stderr
    return made.stdout.strip().splitlines()[-1]


@pytest.mark.blender
@pytest.mark.parametrize("version", ["current"] + OTHER_BPY_VERSIONS)
def test_install_enable_use_disable_remove(version, tmp_path):
    python = python_for(version)
    # Built by that version's own extension builder, installed by that version's installer.
    build = subprocess.run(
        [python, os.path.join(ROOT, "scripts", "build_extension.py"), "--platforms", "linux-x64", "--output-dir", str(tmp_path / "dist")],
        capture_output=True, text=True,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    zips = list((tmp_path / "dist").glob("*linux_x64.zip"))
    assert len(zips) == 1, build.stdout
    linux_zip = zips[0]
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    result_path = tmp_path / "result.json"
    run = subprocess.run(
        [python, os.path.join(ROOT, "tests", "e2e_install_script.py"), str(linux_zip), str(result_path)],
        env=env, capture_output=True, text=True, cwd=str(tmp_path),
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Error" not in run.stderr and "Traceback" not in run.stderr, run.stderr
    result = json.loads(result_path.read_text())
    assert result["install"] == ["FINISHED"]
    assert result["enabled"] == [True, True]
    assert result["bundled_embreex"], "the embreex wheel in the zip was not installed"
    assert result["scene_property"] and result["panel"]
    np.testing.assert_allclose(result["basis_north_pole"], [0.5 / np.sqrt(np.pi), 0, np.sqrt(3 / (4 * np.pi)), 0])
    assert result["disable"] == ["FINISHED"]
    assert not result["scene_property_after_disable"] and not result["panel_after_disable"]
    assert result["handlers_after_disable"] == []
    assert result["uninstall"] == ["FINISHED"]
    assert not result["files_left"]
