"""Export of baked objects to a binary glTF (.glb) with the transfer and the world lighting.

Blender's own glTF exporter writes the file: the transfer is copied into temporary FLOAT_COLOR
attributes `_PRT_T0`, `_PRT_T1`, ... (custom attributes it exports as VEC4 FLOAT accessors),
rotated into glTF's Y-up frame, and with split lights the contact tangent `_PRT_CONTACT`
(contact); the PRT metadata and the lighting are added to the JSON chunk
afterwards (glb). The user's attributes, selection and active object are restored in every
case, and the file appears only when complete (temporary file renamed). The world's prefiltered
cube map and irradiance go in EXT_lights_image_based (ibl). docs/export.md is the format.
"""

import os
import uuid

import bpy
import numpy as np

from ...core.lights.extraction import MAX_LIGHTS
from ...core.lights.light_sh import lights_sh
from ...core.lights.samples import shadow_angle
from ...core.lights.shadow_views import light_samples, shadow_views
from ...core.sh import rotation as _rotation
from ..scene import lighting as _lighting, storage
from ..world import nodes as _nodes, projection as _world
from ..world.nodes import WorldError
from . import contact, glb, ibl, quantise, specular, texels

ATTRIBUTE_PREFIX = "_PRT_T"
WEB_WIDE_VIEWS = 32  # the web viewer's wide maps (MAX_WIDE_VIEWS of web/src/shadows.js)
EXTRAS_KEY = "PRT_lighting"
FORMAT_VERSION = 1  # scene extras, and mesh extras of a float32 transfer (quantise.VERSION: quantised,
# texels.VERSION: per texel)
DEFAULT_TRANSFER = "snorm16"  # docs/export.md, "Quantised transfer": chosen by size and error measured

# Blender (Z up) to glTF (Y up) coordinates, as the exporter's export_yup: (x, y, z) -> (x, z, -y).
BLENDER_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


# Blender's glTF exporter as the export runs it (the file path and the active-colour rule aside).
EXPORTER_OPTIONS = {
    "export_format": "GLB",
    "use_selection": True,
    "export_attributes": True,
    "export_cameras": True,
    "export_extras": True,
    "export_yup": True,
    "export_apply": False,
    "export_animations": False,
    "export_all_vertex_colors": False,
}


class ExportError(ValueError):
    """An export refused or failed, with a message for the user."""


def attribute_name(k):
    return f"{ATTRIBUTE_PREFIX}{k}"


def to_gltf_frame(coeffs):
    """SH coefficients (n*n, ...) of a function in a Blender frame -> the same function in the
    glTF frame (f'(C w) = f(w), C = BLENDER_TO_GLTF)."""
    coeffs = np.asarray(coeffs, dtype=np.float64)
    n = int(round(np.sqrt(coeffs.shape[0])))
    return _rotation.rotation_matrix(BLENDER_TO_GLTF, n) @ coeffs


def _ensure_exporter():
    if "gltf" in dir(bpy.ops.export_scene):
        return
    import addon_utils

    addon_utils.enable("io_scene_gltf2", default_set=True, persistent=False)
    if "gltf" not in dir(bpy.ops.export_scene):
        raise ExportError("Blender's glTF exporter (io_scene_gltf2) is not available")


def _check_path(path):
    path = os.path.abspath(bpy.path.abspath(str(path)))
    if not path.lower().endswith(".glb"):
        raise ExportError(f"the export file must end in .glb: '{path}'")
    folder = os.path.dirname(path)
    if not os.path.isdir(folder):
        raise ExportError(f"cannot write '{path}': the folder '{folder}' does not exist")
    if not os.access(folder, os.W_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        raise ExportError(f"cannot write '{path}': permission denied")
    if os.path.isdir(path):
        raise ExportError(f"cannot write '{path}': it is a folder")
    return path


def _plan(objects, scene):
    """[(object, BakeRecord or None)] of the objects to export; raises ExportError.
    objects=None: the scene's baked meshes and its camera (a viewer opens at the camera's view)."""
    if objects is None:
        objects = [o for o in scene.objects if o.type == "MESH" and o.data.get(storage.RECORD) is not None]
        camera = scene.camera
        if objects and camera is not None and camera.type == "CAMERA":
            if camera.name in bpy.context.view_layer.objects:
                objects.append(camera)
    elif isinstance(objects, bpy.types.Object):
        objects = [objects]
    objects = list(objects)
    plan, layer = [], bpy.context.view_layer
    for obj in objects:
        if obj.type != "MESH":
            plan.append((obj, None))
            continue
        state = storage.bake_state(obj.data)
        if state.status == "STALE":
            raise ExportError(
                f"'{obj.name}': the bake is stale ({state.reason}), so the export would not match the mesh"
            )
        bake = state.bake if state.status == "FRESH" else None
        plan.append((obj, bake))
    if not any(bake is not None for _o, bake in plan):
        raise ExportError("nothing to export: none of the objects holds a PRT bake (bake them first)")
    for obj, _bake in plan:
        if obj.name not in layer.objects:
            raise ExportError(f"'{obj.name}' is not in the view layer '{layer.name}', so it cannot be exported")
    return plan


def _sample_indices(light, views):
    """Per view of `light` (core.lights.shadow_views.ShadowView, in order) the indices of its samples in
    light.samples, or None for a light without samples (its one view is its direction). The views
    hold copies of the light's first samples (normalised) and weights (renormalised): each one is
    found by sorting both sets of (direction, weight) rows, which pairs them one to one."""
    if light.samples is None:
        return [None] * len(views)
    dirs, weights = light_samples(light)
    want = np.c_[dirs, weights]
    got = np.concatenate([np.c_[v.samples, v.weights] for v in views])
    if got.shape != want.shape:
        raise ExportError("the shadow views do not hold each of the light's samples once")
    have, need = np.lexsort(got.T[::-1]), np.lexsort(want.T[::-1])
    if not np.array_equal(got[have], want[need]):
        raise ExportError("the shadow views' samples are not the light's")
    index = np.empty(len(got), dtype=np.int64)
    index[have] = need
    return [part.tolist() for part in np.split(index, np.cumsum([len(v.weights) for v in views])[:-1])]


def _views_extras(lights):
    """Per light the JSON of its shadow views (core.lights.shadow_views at the web viewer's full budget
    of wide maps, WEB_WIDE_VIEWS: the viewer runs on a GPU, the viewport may draw fewer on a heavy
    scene), glTF frame. Only the first MAX_LIGHTS lights are drawn (the viewport's MAX_SUNS): later
    ones get []."""
    views = shadow_views(lights[:MAX_LIGHTS], max_wide_views=WEB_WIDE_VIEWS)
    out = [[] for _ in lights]
    for index, light in enumerate(lights[:MAX_LIGHTS]):
        mine = [v for v in views if v.light == index]
        for view, samples in zip(mine, _sample_indices(light, mine)):
            out[index].append(
                {
                    "direction": (BLENDER_TO_GLTF @ view.direction).tolist(),
                    "angle": float(view.angle),
                    "samples": samples,
                    "wide": bool(view.wide),
                }
            )
    return out


def world_extras(scene):
    """The scene's lighting as JSON-ready data in glTF's world frame; raises ExportError."""
    coeffs = _world.current_world_coeffs(scene)
    if coeffs is None:
        raise ExportError("the scene has no PRT lighting: project the world first (PRT tab > Project World)")
    world_lights = list(_lighting.world_lights(scene))
    lights = []
    for light, views in zip(world_lights, _views_extras(world_lights)):
        lights.append(
            {
                "direction": (BLENDER_TO_GLTF @ np.asarray(light.direction, dtype=np.float64)).tolist(),
                "power": np.asarray(light.power, dtype=np.float64).tolist(),
                "angle": float(light.angle),
                # The shading's samples (docs/lights.md, "Samples"); null for a light without.
                "samples": None if light.samples is None else (light.samples @ BLENDER_TO_GLTF.T).tolist(),
                "weights": None if light.weights is None else light.weights.tolist(),
                "shadow_angle": shadow_angle(light),
                # The shadow maps a viewer draws for it (docs/export.md, "Shadow views").
                "views": views,
            }
        )
    n = int(round(np.sqrt(coeffs.shape[0])))
    return {
        "version": FORMAT_VERSION,
        "order": n,
        "frame": "GLTF_WORLD",
        "sh_convention": "REAL_ORTHONORMAL_NO_CONDON_SHORTLEY",
        "coefficients": to_gltf_frame(coeffs).tolist(),
        "lights": lights,
        "lights_coefficients": to_gltf_frame(lights_sh(world_lights, n)).tolist(),
        "mapping_rotation_euler_xyz": [float(a) for a in _nodes.mapping_rotation_euler(scene.world)]
        if scene.world is not None
        else [0.0, 0.0, 0.0],
        "blender_sh_rotation": _world.current_rotation(scene).tolist(),
        "view": {
            "exposure": float(scene.view_settings.exposure),
            "view_transform": str(scene.view_settings.view_transform),
        },
    }


def mesh_extras(bake):
    texel = bake.domain == "TEXEL"  # (its images and UV map: texels.annotate)
    return {
        "version": FORMAT_VERSION,
        "order": bake.order,
        "coefficients": bake.order * bake.order,
        "attributes": [] if texel else [attribute_name(k) for k in range(bake.count)],
        "domain": bake.domain,
        "frame": "GLTF_NODE_LOCAL",
        "sh_convention": "REAL_ORTHONORMAL_NO_CONDON_SHORTLEY",
        "per_channel": bake.channels == 3,
        "shadows": bool(bake.record.get("shadows", False)),
        "bounces": int(bake.record.get("bounces", 0)),
        "bounce_channels": int(bake.channels),
        "bounce_attributes": []
        if texel
        else [attribute_name(k) for k in range(bake.count, bake.count * (1 + bake.channels))],
        "transfer_encoding": "float32",  # quantise.quantise changes it (and version, and adds decode)
    }


def _add_attributes(mesh, bake, added):
    """Write the transfer (rotated to glTF's frame) as _PRT_Tk, appending each name to `added`;
    a bounced bake's channels follow the direct block, padded the same (docs/export.md)."""
    parts = [storage.read_transfer(mesh, bake)]
    bounced = storage.read_bounce(mesh, bake)
    if bounced is not None:
        parts += [bounced[:, c] for c in range(bounced.shape[1])]
    packed = np.zeros((parts[0].shape[0], bake.count * 4 * len(parts)), dtype=np.float32)
    for p, values in enumerate(parts):
        rotated = to_gltf_frame(values.astype(np.float64).T).T.astype(np.float32)
        packed[:, bake.count * 4 * p : bake.count * 4 * p + rotated.shape[1]] = rotated
    for k in range(bake.count * len(parts)):
        name = attribute_name(k)
        if mesh.attributes.get(name) is not None:
            raise ExportError(f"mesh '{mesh.name}' already has an attribute '{name}'; rename it to export")
        added.append(name)
        mesh.attributes.new(name, "FLOAT_COLOR", bake.domain)
        mesh.attributes[name].data.foreach_set("color", np.ascontiguousarray(packed[:, 4 * k : 4 * k + 4]).ravel())


def _state(plan):
    layer = bpy.context.view_layer
    meshes = {o.data for o, bake in plan if bake is not None}
    colors = {m: (m.color_attributes.active_color_name, m.color_attributes.default_color_name) for m in meshes}
    return {
        "selected": [o for o in layer.objects if o.select_get()],
        "active": layer.objects.active,
        "colors": colors,
    }


def _restore(state, added):
    layer = bpy.context.view_layer
    for mesh, names in added:
        for name in names:
            attr = mesh.attributes.get(name)
            if attr is not None:
                mesh.attributes.remove(attr)
    for mesh, (active, default) in state["colors"].items():
        names = {a.name for a in mesh.color_attributes}
        if active in names and mesh.color_attributes.active_color_name != active:
            mesh.color_attributes.active_color_name = active
        if default in names and mesh.color_attributes.default_color_name != default:
            mesh.color_attributes.default_color_name = default
        mesh.update()
    selected = set(state["selected"])
    for obj in layer.objects:
        want = obj in selected
        if obj.select_get() != want:
            obj.select_set(want)
    layer.objects.active = state["active"]


def _annotate(document, plan, world):
    """Add the extras: the scene's lighting, and each baked mesh's metadata (by node name);
    returns {glTF mesh index: (Blender mesh, bake)} of the texel bakes."""
    scenes = document.get("scenes", [])
    for gltf_scene in scenes:
        gltf_scene.setdefault("extras", {})[EXTRAS_KEY] = world
    by_name = {o.name: bake for o, bake in plan if bake is not None}
    data = {o.name: o.data for o, bake in plan if bake is not None}
    meshes = document.get("meshes", [])
    found, texel = set(), {}
    for node in document.get("nodes", []):
        bake = by_name.get(node.get("name"))
        if bake is None or "mesh" not in node:
            continue
        if bake.domain == "TEXEL":
            texel[node["mesh"]] = (data[node["name"]], bake)
        mesh = meshes[node["mesh"]]
        extras = mesh.get("extras")
        mesh["extras"] = extras = extras if isinstance(extras, dict) else {}
        extras[EXTRAS_KEY] = mesh_extras(bake)
        found.add(node["name"])
    missing = sorted(set(by_name) - found)
    if missing:
        raise ExportError(f"the glTF exporter wrote no mesh for {', '.join(missing)}")
    return texel


def _run_exporter(path, meshes):
    """Blender's glTF exporter on the selection, to `path`; raises ExportError."""
    # A mesh without material exports its active colour attribute as COLOR_0: not when that is
    # a transfer attribute (the first colour attribute a bake creates becomes the active one).
    active_is_transfer = any(
        storage.is_transfer_attribute(m.color_attributes.active_color_name or "")
        or (m.color_attributes.active_color_name or "").startswith(ATTRIBUTE_PREFIX)
        for m in meshes
    )
    try:
        return bpy.ops.export_scene.gltf(
            filepath=path, **EXPORTER_OPTIONS, export_active_vertex_color_when_no_material=not active_is_transfer
        )
    except RuntimeError as error:
        raise ExportError(f"the glTF exporter failed: {error}") from None


def export_gltf(path, objects=None, scene=None, environment_size=ibl.DEFAULT_SIZE, transfer=DEFAULT_TRANSFER):
    """Write the objects (default: the scene's baked meshes) to `path` (.glb); returns the path.
    environment_size: the EXT_lights_image_based cube map's mip-0 face size (a power of two),
    0 to leave the extension out. transfer: how the transfer is stored, "snorm16" (default),
    "snorm8" or "float32" (quantise.TRANSFER_ENCODINGS). Raises ExportError (a ValueError) with a
    user-facing message; then no file is left."""
    if transfer not in quantise.TRANSFER_ENCODINGS:
        raise ExportError(f"unknown transfer encoding '{transfer}' (one of {', '.join(quantise.TRANSFER_ENCODINGS)})")
    scene = bpy.context.scene if scene is None else scene
    if scene != bpy.context.scene:
        raise ExportError(f"only the current scene can be exported (not '{scene.name}'): switch to it first")
    path = _check_path(path)
    if bpy.context.mode != "OBJECT":
        raise ExportError("leave Edit Mode (or any other mode) to export")
    plan = _plan(objects, scene)
    world = world_extras(scene)
    environment = None
    if environment_size:
        try:
            environment = ibl.environment(scene, world, environment_size)
        except (WorldError, ValueError) as error:
            raise ExportError(f"the environment map cannot be made: {error}") from None
    try:
        glossy = specular.prepare(scene) if specular.enabled(scene) else None
    except (WorldError, ValueError) as error:
        raise ExportError(f"the specular sky cannot be made: {error}") from None
    _ensure_exporter()
    state = _state(plan)
    added = []
    temp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.{uuid.uuid4().hex[:8]}.tmp.glb")
    try:
        for obj, bake in plan:
            if bake is None or obj.data in [m for m, _n in added]:
                continue
            added.append((obj.data, []))
            if bake.domain != "TEXEL":
                _add_attributes(obj.data, bake, added[-1][1])
            if world["lights"]:  # (only a viewer's shadow maps read it: docs/export.md, "Contact tangent")
                contact.add_attribute(obj.data, bake, added[-1][1], BLENDER_TO_GLTF)
        for obj in bpy.context.view_layer.objects:
            obj.select_set(False)
        for obj, _bake in plan:
            obj.select_set(True)
        bpy.context.view_layer.objects.active = plan[0][0]
        result = _run_exporter(temp, [m for m, _n in added])
        if "FINISHED" not in result or not os.path.isfile(temp):
            raise ExportError("the glTF exporter did not write the file")
        document, chunks = glb.read(temp)
        texel = _annotate(document, plan, world)
        chunks = quantise.quantise(document, chunks, transfer, EXTRAS_KEY)
        texels.annotate(document, chunks, texel, to_gltf_frame, texels.encoding_for(transfer), EXTRAS_KEY)
        chunks = contact.store(document, chunks, EXTRAS_KEY)
        if environment is not None:
            ibl.write(document, chunks, environment[0], environment[1], glb.CHUNK_BIN)
        materials = {s.material.name: (s.material, o.data) for o, _b in plan for s in o.material_slots if s.material}
        if glossy is not None:
            specular.write(document, chunks, glb.CHUNK_BIN, glossy, materials, EXTRAS_KEY)
        glb.write(temp, document, chunks)
        os.replace(temp, path)
    except OSError as error:
        raise ExportError(f"cannot write '{path}': {error.strerror or error}") from None
    finally:
        if os.path.exists(temp):
            os.remove(temp)
        _restore(state, added)
    return path
