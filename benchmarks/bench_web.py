"""Web benchmark in headless Chromium: frame time of the PRT material against MeshStandardMaterial with the same environment (PMREM) at 1M triangles, and the demo file's load time.

    .venv/bin/python benchmarks/bench_web.py [--triangles 1000000] [--rounds 15] [--order 8]

The demo scene (scripts/demo.py) is baked at --order with 64 directions and exported as the
demo exports it (the default snorm16 transfer, the 128 px environment). The page
(web/tools/bench_page.js, in Debian's Chromium on SwiftShader: software WebGL2 on the CPU) loads
that file through GLTFLoader and the plugin (the load time: parse plus the first frame), then
draws a torus knot of about --triangles triangles at 800x600 three ways, in turn, each frame
finished by reading one pixel back: the PRT material (order 8 per-vertex transfer summed every
frame from a texture, the plugin's relight: false, the file's lighting), the same relit once per
lighting change ("prt_relit", the plugin's default: one vec4 read per vertex a frame) and relit
before every frame with the lighting turned ("prt_relit_turning"), the same from packed integer
vertex attributes (the plugin's transferSource 'packed', "prt_packed"), the relit one with the
Principled specular ("prt_specular": the file's residual sky and split-sum table, the constants
of Suzanne's Principled material, roughness 0.5, metallic 0; the demo is exported with the
scene's Specular on; printed also against "prt_relit", the same frame diffuse only), the same
with the view turned a little before every frame ("prt_specular_moving": the occlusion pass,
web/src/occlusion.js, runs in every frame), with --lights the same with the file's
split lights and their shadow views (PCSS per pixel) and with them unshadowed, and MeshStandardMaterial (roughness 0.5) with the file's world as a PMREM
environment. Ratios are of medians measured side by side in one run; absolute times are for
this machine only.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "scripts"))

import demo


def tool(script):
    run = subprocess.run(["bash", os.path.join(ROOT, "scripts", script)], capture_output=True, text=True, check=True)
    return run.stdout.strip().splitlines()[-1]


def glossy_material(roughness):
    """A Principled material (base 0.8 grey, metallic 0) of this roughness, as MeshStandardMaterial's."""
    import bpy

    material = bpy.data.materials.new("Glossy")
    if material.node_tree is None:  # Blender 4.x: new materials have no nodes
        material.use_nodes = True
    bsdf = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = 0.0
    return material


def export_demo(folder, order):
    import prt_addon
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    offscreen.ensure_gpu()
    prt_addon.register()
    scene = demo.build_scene(demo.bundled_hdri_path("forest"))
    # With the scene's Specular on and a glossy Principled material on Suzanne, the file carries
    # the specular block (residual sky, split-sum table) and that material's constants.
    scene.prt_display.specular = True
    scene.objects["Suzanne"].data.materials.append(glossy_material(roughness=0.5))
    api.project_world(order=order)
    api.bake([scene.objects["Suzanne"], scene.objects["Ground"]], order=order, samples=64)
    return api.export_gltf(os.path.join(folder, "prt_demo.glb"), scene=scene)


def print_ratio(name, other, values, others):
    """The median of the per-round ratios of two variants (drawn back to back), its range, the ratio of medians."""
    ratios = sorted(a / b for a, b in zip(values, others))
    print(
        f"{name} / {other}: median of per-round ratios {statistics.median(ratios):.2f} "
        f"(range {ratios[0]:.2f}-{ratios[-1]:.2f}); ratio of medians "
        f"{statistics.median(values) / statistics.median(others):.2f}"
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--order", type=int, default=8)
    parser.add_argument("--transfer-order", type=int, help="the large mesh's transfer order (default --order)")
    parser.add_argument("--glb", help="a .glb to use instead of baking the demo scene")
    parser.add_argument(
        "--lights", action="store_true", help="also PRT with the file's split lights (slow in software)"
    )
    parser.add_argument("--verbose", action="store_true", help="the page's progress on stderr")
    args = parser.parse_args()
    folder = tempfile.mkdtemp(prefix="prt_bench_web_")
    glb = args.glb or export_demo(folder, args.order)
    job = {
        "chromium": tool("setup_chromium.sh"),
        "glb": glb,
        "out": os.path.join(folder, "bench"),
        "triangles": args.triangles,
        "rounds": args.rounds,
        "lights": args.lights,
        "order": args.transfer_order or args.order,
    }
    modules = tool("setup_node.sh")
    with open(os.path.join(folder, "job.json"), "w") as f:
        json.dump(job, f)
    run = subprocess.run(
        ["node", os.path.join(ROOT, "web", "tools", "bench_headless.mjs"), os.path.join(folder, "job.json")],
        stdout=subprocess.PIPE,
        stderr=None if args.verbose else subprocess.PIPE,
        text=True,
        env=dict(os.environ, PRT_NODE_MODULES=modules),
    )
    if run.returncode != 0:
        sys.exit((run.stderr or "")[-3000:])
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    load, setup, times = summary["load"], summary["setup"], summary["times"]
    print(
        f"renderer: {setup['renderer']}; {setup['triangles']} triangles, {setup['vertices']} vertices, {setup['size']}"
    )
    print(
        f"demo file ({load['bytes'] / 1e6:.2f} MB, order {args.order}): GLTFLoader + plugin {load['parse']:.0f} ms, "
        f"first frame (shaders, shadow maps) {load['firstFrame']:.0f} ms"
    )
    print(
        "first frame of each (shaders; the split lights' shadow maps):",
        {k: round(v) for k, v in setup["prepare"].items()},
    )
    medians = {name: statistics.median(values) for name, values in times.items()}
    for name, values in times.items():
        print(
            f"{name}: median {medians[name]:.1f} ms (min {min(values):.1f}, max {max(values):.1f}, {len(values)} frames)"
        )
    # Each round draws every variant once, back to back: the ratio per round, then its median.
    standard = times["standard"]
    names = ("prt", "prt_packed", "prt_relit", "prt_relit_turning", "prt_specular", "prt_specular_moving", "prt_lights")
    for name in (*names, "prt_lights_unshadowed"):
        if name in times:
            print_ratio(name, "MeshStandardMaterial", times[name], standard)
    if "prt_specular" in times:
        print_ratio("prt_specular", "prt_relit (diffuse only)", times["prt_specular"], times["prt_relit"])
        print_ratio("prt_specular_moving", "prt_relit (diffuse only)", times["prt_specular_moving"], times["prt_relit"])
        change = setup["specularChange"]
        print(
            f"prt_specular differs from prt_relit by {change['mean']:.1f}/255 on average over {change['pixels']} pixels"
        )
    else:
        print("prt_specular: not drawn (the file has no specular block or no Principled material)")
    errors = [m for m in summary["console"] if m.startswith(("error", "pageerror"))]
    if errors:
        print("console errors:", errors)
    sys.stdout.flush()
    os._exit(0)  # (bpy 4.2 crashes at exit after a glTF export: docs/export.md)


if __name__ == "__main__":
    main()
