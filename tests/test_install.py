"""End to end, as a user would: build the linux-x64 zip, install it with Blender's own extension
installer into a fresh user directory, enable, use, disable and remove it."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    build = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "build_extension.py"), "--platforms", "linux-x64", "--output-dir", str(out)],
        capture_output=True, text=True,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    zips = list(out.glob("*linux_x64.zip"))
    assert len(zips) == 1, build.stdout
    return zips[0]


@pytest.mark.blender
def test_install_enable_use_disable_remove(linux_zip, tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    result_path = tmp_path / "result.json"
    run = subprocess.run(
        [sys.executable, os.path.join(ROOT, "tests", "e2e_install_script.py"), str(linux_zip), str(result_path)],
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
