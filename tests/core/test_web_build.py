"""The web viewer without a browser or bpy: its JS SH rotation against the core (node), its build's refusals."""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers.web import (
    ROOT,
    _tool,
)

from prt_addon.core.sh import basis as sh, frames, rotation

SH_ROTATION_JS = os.path.join(ROOT, "web", "src", "sh_rotation.js")
NODE_ROTATION = """
import { rotationMatrix, frameRotation, lightInLocalFrame } from %s;
import fs from 'node:fs';
const cases = JSON.parse(fs.readFileSync(0, 'utf8'));
const out = cases.map((c) => ({
  matrix: Array.from(rotationMatrix(c.rotation, c.order)),
  frame: frameRotation(c.linear),
  local: lightInLocalFrame(c.light, c.linear, c.order, c.turn),
}));
console.log(JSON.stringify(out));
"""


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_js_rotation_matches_the_core(tmp_path):
    """web/src/sh_rotation.js gives the core's rotation matrices (orders 1-8, random rotations),
    frame rotations (scaled, sheared, mirrored) and local-frame lights to 1e-10."""
    if shutil.which("node") is None:
        pytest.skip("node is needed to run the viewer's JavaScript (install Node.js)")
    rng = np.random.default_rng(17)
    cases = []
    for order in range(1, 9):
        for _ in range(3):
            linear = (
                _random_rotation(rng) @ np.diag(rng.uniform(0.3, 2.0, 3)) @ (np.eye(3) + 0.2 * rng.normal(size=(3, 3)))
            )
            if rng.uniform() < 0.5:
                linear = linear @ np.diag([-1.0, 1.0, 1.0])
            light_order = int(rng.integers(1, 10))
            cases.append(
                {
                    "order": order,
                    "rotation": _random_rotation(rng).ravel().tolist(),
                    "linear": linear.ravel().tolist(),
                    "turn": _random_rotation(rng).ravel().tolist(),
                    "light": rng.normal(size=(light_order * light_order, 3)).tolist(),
                }
            )
    script = tmp_path / "rotation.mjs"
    script.write_text(NODE_ROTATION % json.dumps("file://" + SH_ROTATION_JS))
    run = subprocess.run(
        ["node", str(script)], input=json.dumps(cases), capture_output=True, text=True, timeout=120, check=False
    )
    assert run.returncode == 0, run.stderr
    results = json.loads(run.stdout)
    worst = 0.0
    for case, got in zip(cases, results, strict=True):
        n = case["order"]
        r = np.array(case["rotation"]).reshape(3, 3)
        expected = rotation.rotation_matrix(r, n)
        worst = max(worst, np.abs(np.array(got["matrix"]).reshape(n * n, n * n) - expected).max())
        linear = np.array(case["linear"]).reshape(3, 3)
        q, mirrored = frames.frame_rotation(linear)
        assert got["frame"]["mirrored"] == mirrored
        assert np.abs(np.array(got["frame"]["rotation"]).reshape(3, 3) - q).max() < 1e-10
        # docs/export.md, Shading steps 1-2, with the world light first turned by `turn`.
        light = np.array(case["light"])
        padded = np.zeros((n * n, 3))
        m = min(n * n, len(light))
        padded[:m] = light[:m]
        turn = np.array(case["turn"]).reshape(3, 3)
        local = rotation.rotation_matrix(q.T @ turn, n) @ padded
        if mirrored:
            local *= ((-1.0) ** sh.band_of_index(n))[:, None]
        assert np.abs(np.array(got["local"]) - local).max() < 1e-10 * max(1.0, np.abs(local).max())
    assert worst < 1e-10, worst


def test_build_refuses_bad_input(tmp_path):
    """build_web.sh says what is wrong with the .glb or the output path, and leaves no page."""
    for tool in ("node", "npm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is needed to build the web viewer (install Node.js)")
    _tool("setup_node.sh")
    no_prt = tmp_path / "plain.glb"
    header = json.dumps({"asset": {"version": "2.0"}, "scenes": [{"nodes": []}]}).encode()
    header += b" " * (-len(header) % 4)
    no_prt.write_bytes(
        b"glTF"
        + (2).to_bytes(4, "little")
        + (20 + len(header)).to_bytes(4, "little")
        + len(header).to_bytes(4, "little")
        + b"JSON"
        + header
    )
    (tmp_path / "text.glb").write_text("not a glb")
    (tmp_path / "file").write_text("")
    cases = [
        (["--glb", str(tmp_path / "missing.glb")], "no such file"),
        (["--glb", str(tmp_path / "text.glb")], "is not a binary glTF"),
        (["--glb", str(no_prt)], "has no PRT lighting"),
        (["--out", str(tmp_path / "file" / "page.html")], "a part of its folder is a file"),
    ]
    for args, message in cases:
        run = subprocess.run(
            ["bash", os.path.join(ROOT, "scripts", "build_web.sh"), *args]
            + ([] if "--out" in args else ["--out", str(tmp_path / "page.html")]),
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert run.returncode == 2 and message in run.stderr, (args, run.stderr)
        assert "at " not in run.stderr  # a message, not a stack trace
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "plain.glb", "text.glb"]
