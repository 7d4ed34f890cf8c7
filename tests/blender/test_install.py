"""End to end, as a user would: build the linux-x64 zip, install it with Blender's own extension
installer into a fresh user directory, enable, use, disable and remove it."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from helpers.paths import ROOT

# The suite itself runs on the bpy of requirements-dev.txt; the install test also runs on the
# other supported Blender versions, each in its own venv made by scripts/bpy_venv.sh.
OTHER_BPY_VERSIONS = ["4.2.23", "4.5.15"]


def python_for(version):
    if version == "current":
        return sys.executable
    made = subprocess.run(
        ["bash", os.path.join(ROOT, "scripts", "bpy_venv.sh"), version], capture_output=True, text=True
    )
    assert made.returncode == 0, made.stderr
    return made.stdout.strip().splitlines()[-1]


def build_linux_zip(python, out_dir, no_wheels=False):
    """The linux-x64 zip, built by that Python's own Blender extension builder."""
    command = [
        python,
        os.path.join(ROOT, "scripts", "build_extension.py"),
        "--platforms",
        "linux-x64",
        "--output-dir",
        str(out_dir),
    ] + (["--no-wheels"] if no_wheels else [])
    build = subprocess.run(command, capture_output=True, text=True)
    assert build.returncode == 0, build.stdout + build.stderr
    zips = list(out_dir.glob("*linux_x64.zip"))
    assert len(zips) == 1, build.stdout
    return zips[0]


def install_and_use(python, linux_zip, tmp_path, mode):
    """Install into a fresh BLENDER_USER_RESOURCES, enable, use, disable, remove; the result."""
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / f"user-{mode}"))
    result_path = tmp_path / f"result-{mode}.json"
    run = subprocess.run(
        [
            python,
            os.path.join(ROOT, "tests", "blender", "e2e_install_script.py"),
            str(linux_zip),
            str(result_path),
            mode,
        ],
        env=env,
        capture_output=True,
        text=True,
        cwd=str(tmp_path),
        timeout=600,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Error" not in run.stderr and "Traceback" not in run.stderr, run.stderr
    assert not [line for line in run.stdout.splitlines() if line.startswith("Error")], run.stdout
    result = json.loads(result_path.read_text())
    result["stdout"] = run.stdout
    return result


def check_lifecycle(result):
    assert result["install"] == ["FINISHED"]
    assert result["enabled"] == [True, True]
    assert result["scene_property"]
    assert result["panel"]
    np.testing.assert_allclose(result["basis_north_pole"], [0.5 / np.sqrt(np.pi), 0, np.sqrt(3 / (4 * np.pi)), 0])
    # Used: a world projected, a sphere on a plane baked and shaded, the lighting rotated.
    assert result["project"] == ["FINISHED"]
    assert all(c > 0 for c in result["light_c0"])  # forest.exr is bright everywhere
    assert result["bake"] == ["FINISHED"]
    assert result["bake_report"]["ok"]
    assert result["bake_report"]["rays_traced"] > 0  # the sphere shadows the plane
    assert result["status"] == ["fresh", "fresh"]
    shade = result["shade"]
    assert shade["finite"] and shade["min"] >= 0.0 and 0.01 < shade["mean"] < 100.0, shade
    # Lit from the sky: the top of the sphere is brighter than its underside (which faces the
    # plane, in its shadow).
    assert sum(shade["top"]) > sum(shade["bottom"]), shade
    assert result["rotate"] == ["FINISHED"]
    assert result["rotation_changes_shading"] > 1e-4
    assert result["draw_handler_while_enabled"]
    # Disabled: nothing of ours is left registered.
    assert result["disable"] == ["FINISHED"]
    assert not result["scene_property_after_disable"]
    assert not result["panel_after_disable"]
    assert result["operators_after_disable"] == []
    assert result["handlers_after_disable"] == []
    assert result["functions_checked_for_timers"] > 50
    # The one timer while enabled is the display's colour check (display/colour.py); none after.
    assert result["timers_while_enabled"] == ["_check", "_poll"]  # (colour tables, display switches)
    assert result["timers_after_disable"] == []
    assert not result["draw_handler_after_disable"]
    assert result["running_bakes_after_disable"] == 0
    assert result["uninstall"] == ["FINISHED"]
    assert not result["files_left"]


@pytest.mark.parametrize("version", ["current"] + OTHER_BPY_VERSIONS)
def test_install_enable_use_disable_remove(version, tmp_path):
    python = python_for(version)
    # Built by that version's own extension builder, installed by that version's installer.
    linux_zip = build_linux_zip(python, tmp_path / "dist")
    result = install_and_use(python, linux_zip, tmp_path, "embree")
    assert result["bundled_embreex"], "the embreex wheel in the zip was not installed"
    assert result["embree_available"]
    check_lifecycle(result)
    assert result["backend"] == "EMBREE"
    assert result["bake_report"]["backend"] == "EMBREE"
    assert result["bake_report"]["note"] == ""


@pytest.mark.parametrize("version", ["current"] + OTHER_BPY_VERSIONS)
def test_without_embree_the_bvhtree_fallback_works_and_says_so(version, tmp_path):
    """As a user on a platform with no embreex wheel: a zip without wheels, embreex unimportable."""
    python = python_for(version)
    linux_zip = build_linux_zip(python, tmp_path / "dist", no_wheels=True)
    result = install_and_use(python, linux_zip, tmp_path, "no-embree")
    assert not result["bundled_embreex"]
    assert not result["embree_available"]
    check_lifecycle(result)
    assert result["backend"] == "BVHTREE"
    assert result["bake_report"]["backend"] == "BVHTREE"
    note = result["bake_report"]["note"]
    assert "Embree (embreex) is not available on this system" in note
    assert "BVH tree fallback" in note
    assert "slower" in note
    # The same sentence is in Blender's report (a WARNING of the operator) and in the panel's
    # bake report (summary_lines).
    assert f"Warning: PRT: {note}" in result["stdout"], result["stdout"]
