"""The Principled spheres scene: roughness x metallic spheres on a ground under a sunny
HDRI, and its renders: PRT's render_view, Cycles with direct light only, EEVEE."""

import math
import os
import tempfile

import numpy as np

from helpers.display_scenes import add_camera
from helpers.worlds import bundled_hdri_path, new_world, use_image

ROUGHNESS = (0.1, 0.3, 0.6, 1.0)
METALLIC = (0.0, 1.0)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def principled_material(bpy, name, base, roughness, metallic):
    """A new material whose Principled BSDF has this base colour, roughness and metallic."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender 4.x: new materials have no nodes
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return mat


def spheres_scene(bpy, scene, hdri="city", size=(160, 96), segments=48):
    """8 spheres (radius 0.45) in two rows (metallic 0 front, 1 back) of four roughnesses on a
    12 x 12 ground, the camera looking down at them; -> (spheres {name: object}, ground)."""
    scene.prt_display.specular = True
    world = new_world(bpy, scene)
    image = bpy.data.images.load(bundled_hdri_path(hdri), check_existing=True)
    use_image(world, image)
    spheres = {}
    for j, metallic in enumerate(METALLIC):
        for i, roughness in enumerate(ROUGHNESS):
            bpy.ops.mesh.primitive_uv_sphere_add(
                segments=segments, ring_count=segments // 2, radius=0.45, location=(1.1 * i - 1.65, 1.2 * j, 0.45)
            )
            obj = bpy.context.active_object
            obj.name = f"r{roughness}_m{int(metallic)}"
            obj.data.shade_smooth()
            obj.data.materials.append(principled_material(bpy, obj.name, (0.8, 0.8, 0.8), roughness, metallic))
            spheres[obj.name] = obj
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=64, y_subdivisions=64, size=12.0)
    ground = bpy.context.active_object
    ground.name = "ground"
    ground.data.materials.append(principled_material(bpy, "ground", (0.5, 0.5, 0.5), 1.0, 0.0))
    cam = add_camera(bpy, scene, location=(0.0, -4.6, 3.2), euler=(math.radians(58.0), 0.0, 0.0), size=size[0])
    scene.render.resolution_y = size[1]
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    bpy.context.view_layer.update()
    return spheres, ground, cam


def _render_exr(bpy, scene):
    folder = tempfile.mkdtemp(prefix="prt_spec_")
    path = os.path.join(folder, "render.exr")
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path)
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    os.remove(path)
    os.rmdir(folder)
    return pixels.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)  # top row first


def cycles_render(bpy, scene, samples, seed=0):
    """(H, W, 3) linear Cycles render with direct light only (0 bounces), top row first."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = 0
    scene.cycles.seed = seed
    scene.render.film_transparent = True
    return _render_exr(bpy, scene)


def eevee_render(bpy, scene, samples=16):
    """(H, W, 3) linear EEVEE render, top row first; raises RuntimeError when EEVEE cannot
    render here."""
    engines = {e.identifier for e in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    engine = "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in engines else "BLENDER_EEVEE"
    scene.render.engine = engine
    scene.eevee.taa_render_samples = samples
    scene.render.film_transparent = True
    return _render_exr(bpy, scene)


def _erode(mask):
    out = mask.copy()
    out[1:] &= mask[:-1]
    out[:-1] &= mask[1:]
    out[:, 1:] &= mask[:, :-1]
    out[:, :-1] &= mask[:, 1:]
    return out


def object_masks(bpy, scene, objects):
    """{name: (H, W) bool} the pixels where each object is seen in render_view (drawn alone it
    gives the full picture's value there: nothing in front), less a pixel at its edges (where
    Cycles' pixel filter mixes it with what is behind)."""
    from prt_addon.blender.display import offscreen

    full = offscreen.render_view(scene)
    masks = {}
    for name, obj in objects.items():
        image = offscreen.render_view(scene, objects=[obj])
        seen = (image[..., 3] > 0.99) & np.all(np.abs(image - full) < 1e-6, axis=-1)
        masks[name] = _erode(seen)
    return masks


def relative_rmse(image, reference, mask):
    """sqrt(mean((Y - Y_ref)^2)) / mean(Y_ref) of luminance over mask."""
    y = image[mask] @ LUMINANCE
    ref = reference[mask] @ LUMINANCE
    return float(np.sqrt(np.mean((y - ref) ** 2)) / max(np.mean(ref), 1e-12))
