"""Drawing: the baked objects with the PRT shader, and the viewport draw handler.

Per redraw (docs/display.md): the world light comes from lighting.world_light; per object it is
rotated into the object's local frame and written into its uniform buffer only when it changed;
the transfer batches come from gpu_cache. With split sun lights (lighting.world_lights) their
shadow views (core.lights.shadow_views) get their maps from shadows.py and the sun variant of the shader
is used. The viewport draws through the scene's display transform (colour.py), whose table the
draw only uploads. Nothing here changes Blender data.
"""

import bpy
import gpu
import numpy as np

from ..scene import storage
from ..scene.albedo_source import slot_sources
from ..scene.lighting import bounce_light_extra, exposure_scale, light_in_local_frame, world_light, world_lights
from ..scene.materials import display_settings
from ..scene.principled import principled_specular
from . import albedo_texture, colour, light_markers, material_maps, sky_texture, spec_occlusion, texel_relight
from .gpu_cache import ObjectState, _object_cache, _prune, clear_caches, get_mesh_entry
from .shader import get_shader, light_ubo_bytes, shader_mode, transfer_vec4s
from .shader_specular import bind_textures, eye_point, slot_ubo
from .shader_suns import MAX_SUNS, suns_ubo_bytes, view_layout
from .shadows import update_shadow_maps

VIEWPORT_DEPTH_BIAS = 2e-5  # clip-space z bias so the overlay wins against the engine's own depth


def baked_objects(scene, view_layer=None, viewport=None):
    """Visible mesh objects of the view layer whose mesh holds a usable bake (stale ones too)."""
    view_layer = view_layer or scene.view_layers[0]
    out = []
    for obj in view_layer.objects:
        if obj.type != "MESH" or storage.RECORD not in obj.data:
            continue
        try:
            if viewport:
                visible = obj.visible_get(view_layer=view_layer, viewport=viewport)
            else:
                visible = obj.visible_get(view_layer=view_layer)
        except TypeError:
            visible = obj.visible_get()
        if visible and obj.mode != "EDIT":
            out.append(obj)
    return out


def draw_objects(scene, view_projection, objects, *, scale=1.0, depth_bias=0.0, depsgraph=None, display_lut=None):
    """Draw `objects` with the PRT shader into the bound framebuffer. Returns the number drawn.

    view_projection: 4x4 (mathutils.Matrix or array) world -> clip. The caller sets depth state.
    depsgraph: the evaluated depsgraph whose deformed meshes are drawn (deformed_mesh);
    None draws every mesh undeformed. display_lut: the 3D texture of colour.texture(scene), to
    write display-linear values through the scene's view transform; None writes linear radiance.
    """
    import mathutils

    light = world_light(scene)
    if light is None:
        return 0
    light_tag = (light.shape, light.tobytes())
    vp = mathutils.Matrix(np.asarray(view_projection, dtype=np.float64).tolist())
    albedo_mode, albedo_attr = display_settings(scene)
    all_lights = list(world_lights(scene)) if objects else []
    suns = all_lights[:MAX_SUNS]
    lights_tag = tuple((tuple(x.direction), tuple(x.power), x.angle) for x in all_lights)
    maps = update_shadow_maps(scene, suns, depsgraph) if suns else None
    layout = view_layout(maps) if maps is not None else None
    use_specular = bool(getattr(getattr(scene, "prt_display", None), "specular", False)) and bool(objects)
    sky = sky_texture.sky_texture(scene) if use_specular else None
    spec_frame = (eye_point(vp), sky_texture.sky_rows(scene), sky, sky_texture.brdf_texture()) if sky else None
    drawn = 0
    for obj in objects:
        info, _problem = storage.usable_bake(obj.data, check_topology=False)
        if info is None:
            continue
        sources = slot_sources(obj) if albedo_mode == "MATERIAL" else None
        slot_specular = [principled_specular(slot.material) for slot in obj.material_slots] if sky else []
        specular = any(x is not None for x in slot_specular)
        spec_maps = material_maps.slot_maps(obj, sources) if specular and sources is not None else []
        spec_maps = spec_maps if any(m.any for m in spec_maps) else []
        map_uvs = material_maps.uv_maps(spec_maps)
        entry = get_mesh_entry(obj.data, info, albedo_mode, albedo_attr, obj, depsgraph, sources, map_uvs)
        if not entry.batches:
            continue
        state = _object_cache.setdefault(obj.as_pointer(), ObjectState())
        mw = np.array(obj.matrix_world, dtype=np.float64)
        # Before the frame's shader is bound: the occlusion passes bind their own.
        slots, inline = (
            _specular_slots(state, entry, info, mw, spec_frame, slot_specular, spec_maps) if specular else ({}, False)
        )
        shader = get_shader(
            info.count, layout, info.channels, info.domain, specular, entry.textured, info.back, bool(spec_maps), inline
        )
        size_key = (info.count, info.channels)
        light_key = (light_tag, mw[:3, :3].tobytes(), info.order, size_key, lights_tag if info.channels else None)
        if state.ubo is None or state.light_key != light_key:
            local = light_in_local_frame(light, mw, info.order)
            bounce = local + bounce_light_extra(obj, all_lights, info.order) if info.channels else None
            data = light_ubo_bytes(local, info.count, bounce)
            if state.ubo is None or state.light_key is None or state.light_key[3] != size_key:
                state.ubo = gpu.types.GPUUniformBuf(data)
            else:
                state.ubo.update(data)
            state.light_key = light_key
        shader.bind()
        shader.uniform_float("mvp", vp @ obj.matrix_world)
        shader.uniform_float("scale", float(scale))
        shader.uniform_float("depth_bias", float(depth_bias))
        shader.uniform_block("light", state.ubo)
        colour.bind(shader, display_lut)
        if suns:
            _bind_suns(shader, state, suns, maps, mw)
        if specular:
            bind_textures(shader, spec_frame)
        if entry.texel_grid is not None:
            shader.uniform_int("texel_grid", entry.texel_grid)
            shader.uniform_sampler("transfer_tx", _relit(state, entry, info.count, info.channels))
            if specular:  # (the occlusion reads the transfer per pixel: texel_occlusion)
                shader.uniform_sampler("texel_tiles_tx", entry.texture)
        elif entry.texture is not None:
            shader.uniform_int("per_row", entry.per_row)
            shader.uniform_sampler("transfer_tx", entry.texture)
        tints, textures = _slot_albedo(obj, sources, entry.textured)
        for mat_index, batch in entry.batches:
            slot = min(mat_index, len(tints) - 1)
            shader.uniform_float("tint", tints[slot])
            if entry.textured:
                shader.uniform_sampler("albedo_tx", textures[slot])
                shader.uniform_int("albedo_mode", sources[slot].sampling if sources else (0, 0))
            if specular:
                ubo, textures, occ = slots[min(mat_index, len(slot_specular) - 1)]
                shader.uniform_block("spec", ubo)
                if textures is not None:
                    material_maps.bind(shader, textures)
                if occ is not None:
                    shader.uniform_sampler("occ_tx", occ)
            batch.draw(shader)
        drawn += 1
    return drawn


def _slot_albedo(obj, sources, textured):
    """(tints, textures) per slot: the sources' colours (white without sources) and, for a
    textured entry, their textures; an image that could not be read draws the viewport colour."""
    if sources is None:
        return [(1.0, 1.0, 1.0, 1.0)], None
    tints = [(*src.colour, 1.0) for src in sources]
    if not textured:
        return tints, None
    textures = albedo_texture.slot_textures(sources)
    for i, tex in enumerate(textures):
        if tex is None:
            tints[i] = tuple(obj.material_slots[i].material.diffuse_color)
            textures[i] = albedo_texture.white()
    return tints, textures


def _specular_slots(state, entry, info, mw, spec_frame, slot_specular, spec_maps):
    """({material slot drawn: (its PRTSpec block, its map textures or None, its full-transfer
    occlusion texture or None)}, whether the frame sums that occlusion itself). While the view
    (or the object, or a lobe) changes from one draw to the next, the frame sums it in its vertex
    shader as it always did; at the first draw that sees the same view again spec_occlusion draws
    it into the slot's texture, which the frame then reads (a white texel for a slot drawn
    diffuse only; None for a texel bake or an inline draw)."""
    total = transfer_vec4s(info.count, info.channels, info.back)
    mode = shader_mode(total, info.domain, entry.textured)
    if state.spec_seen is None:
        state.spec_seen = {}
    out, keys = {}, {}
    for mat_index, _batch in entry.batches:
        slot = min(mat_index, len(slot_specular) - 1)
        if slot in out:
            continue
        params, extra, textures = slot_specular[slot], b"", None
        if spec_maps:
            maps = spec_maps[min(slot, len(spec_maps) - 1)]
            data = material_maps.slot_data(maps, params if params is not None else (0.5, 0.0, 0.04))
            params, extra, textures = (data[0] if params is not None else None), data[1], data[2]
        out[slot] = (slot_ubo(state, slot, mw, spec_frame, params, extra), textures, None)
        if mode != "TEXEL" and params is not None:
            keys[slot] = (entry, spec_occlusion.view_key(spec_frame, mw, params, extra))
    inline = any(state.spec_seen.get(slot) != key for slot, key in keys.items())
    state.spec_seen = keys
    if mode == "TEXEL" or inline:
        return out, inline
    layout = (mode, info.count, total, bool(spec_maps))
    for slot, (ubo, textures, _none) in out.items():
        occ = albedo_texture.white()  # (a diffuse-only slot reads none)
        if slot in keys:
            occ = spec_occlusion.update(state, slot, entry, ubo, keys[slot][1], layout)
        out[slot] = (ubo, textures, occ)
    return out, False


def _relit(state, entry, count, channels):
    """The object's relit radiance texture (texel_relight.Relit: the front's, and beside it the
    back's of an open mesh), drawn again when the light or the bake changed."""
    key = (state.light_key, id(entry))
    back = entry.back_texture is not None
    if state.relit is None or state.relit.resolution != entry.texel_grid[0] or state.relit.back != back:
        state.relit = texel_relight.Relit(entry.texel_grid[0], back)
        state.relit_key = None
    if state.relit_key != key:
        back_tiles = entry.back_texture
        texel_relight.relight(state.relit, entry.texture, entry.texel_grid, count, state.ubo, channels, back_tiles)
        state.relit_key = key
    return state.relit.texture


def _bind_suns(shader, state, suns, maps, matrix_world):
    data = suns_ubo_bytes(suns, maps, matrix_world)
    if state.suns_ubo is None:
        state.suns_ubo = gpu.types.GPUUniformBuf(data)
    elif state.suns_bytes != data:
        state.suns_ubo.update(data)
    state.suns_bytes = data
    shader.uniform_block("suns", state.suns_ubo)
    shader.uniform_sampler("sharp_maps", maps.sharp)
    shader.uniform_sampler("wide_maps", maps.wide)


def _draw_callback():
    draw_viewport(bpy.context)


def draws_in(space):
    """Whether the overlay draws in this 3D View: in Solid shading only. Material Preview and
    Rendered show Blender's own lighting (EEVEE's or Cycles' image), left as it is for comparison."""
    shading = getattr(space, "shading", None)
    return shading is None or getattr(shading, "type", "SOLID") == "SOLID"


def draw_viewport(context):
    """What the viewport's draw handler draws, for the 3D View of `context` (its scene, view layer,
    space and region data): the baked objects over the engine's image, in Solid shading."""
    scene = context.scene
    settings = getattr(scene, "prt", None)
    if settings is None or not settings.show_display or not draws_in(context.space_data):
        return
    region_data = context.region_data
    if region_data is None:
        return
    objects = baked_objects(scene, context.view_layer, context.space_data)
    if not objects:
        return
    depth_mask = gpu.state.depth_mask_get()
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.depth_mask_set(True)
    try:
        draw_objects(
            scene,
            region_data.perspective_matrix,
            objects,
            scale=exposure_scale(scene),
            depth_bias=VIEWPORT_DEPTH_BIAS,
            depsgraph=context.evaluated_depsgraph_get(),
            display_lut=colour.texture(scene),  # (built by colour's timer, never here)
        )
    finally:
        gpu.state.depth_mask_set(depth_mask)
        gpu.state.depth_test_set("NONE")
    _prune(objects)


_draw_handle = None


def draw_handle():
    """The current draw-handler handle (None when not installed); tests use it."""
    return _draw_handle


def add_draw_handler():
    global _draw_handle
    if _draw_handle is None:
        _draw_handle = bpy.types.SpaceView3D.draw_handler_add(_draw_callback, (), "WINDOW", "POST_VIEW")
    light_markers.add_handler()  # after ours: the markers are drawn over the objects
    return _draw_handle


def remove_draw_handler():
    global _draw_handle
    if _draw_handle is not None:
        try:
            bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
        except ValueError:
            pass
        _draw_handle = None
    light_markers.remove_handler()
    clear_caches()
