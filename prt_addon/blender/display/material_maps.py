"""Roughness, Metallic, Specular IOR Level and IOR images in the Principled specular: textures, GLSL, per-slot data.

A slot whose Principled BSDF takes one of these from an image (scene.principled_maps) is drawn
with the textured shader's UV (albedo_texture) and a variant of the specular shader
(shader.get_shader(spec_maps=True)): per pixel, each mapped input is its image's channel looked
up as the node samples it (albedo_texture.sampler_glsl), the others the slot's constants; the
dielectric F0 is ((IOR - 1) / (IOR + 1))^2 x 2 x level, IOR and level each the pixel's or the
constant. The full transfer's occlusion (per vertex, shader_specular.occlusion_lines in
spec_occlusion's pass; per pixel for a texel bake) is computed for two lobes, at the smallest and the
largest roughness of the slot's image, and mixed per pixel linearly in roughness between them
(exact for an image of two values). Without a map the shader and its output are as before.
"""

import functools

import gpu
import numpy as np

from ...core.specular import occlusion
from .. import caches
from ..scene.albedo_source import slot_sources
from ..scene.principled_maps import RANGES, map_pixels, mesh_maps
from . import albedo_texture, shader_specular, texel_occlusion

NAMES = ("rough", "metal", "level", "ior")
SLOTS = (6, 7, 8, 10)  # sampler slots (albedo_texture.ALBEDO_SLOT is 5, the colour table 9)

GLSL = (
    """
float spec_roughness;
float spec_metallic;
float spec_f0d;
float spec_occ_t;
ivec2 rough_mode;
ivec2 metal_mode;
ivec2 level_mode;
ivec2 ior_mode;
"""
    + "".join(albedo_texture.sampler_glsl(name) for name in NAMES)
    + """
void spec_maps_setup()
{
  spec_roughness = spec.material.x;
  spec_metallic = spec.material.y;
  spec_f0d = spec.material.z;
  rough_mode = ivec2(spec.maps[0].yz);
  metal_mode = ivec2(spec.maps[1].yz);
  level_mode = ivec2(spec.maps[2].yz);
  ior_mode = ivec2(spec.maps[3].yz);
  if (spec.maps[0].x > 0.5) {
    spec_roughness = rough_at(albedo_uv).r;
  }
  if (spec.maps[1].x > 0.5) {
    spec_metallic = metal_at(albedo_uv).r;
  }
  if (spec.maps[2].x > 0.5 || spec.maps[3].x > 0.5) {
    float per_level = spec.maps[4].x;  // ((IOR - 1) / (IOR + 1))^2 x 2 of the constant IOR
    if (spec.maps[3].x > 0.5) {
      float ior = ior_at(albedo_uv).r;
      float r = (ior - 1.0) / (ior + 1.0);
      per_level = 2.0 * r * r;
    }
    float level = spec.maps[2].x > 0.5 ? level_at(albedo_uv).r : spec.maps[4].w;
    spec_f0d = clamp(per_level * level, 0.0, 1.0);
  }
  spec_occ_t = clamp((spec_roughness - spec.maps[4].y) / max(spec.maps[4].z - spec.maps[4].y, 1e-6), 0.0, 1.0);
}
"""
)


def ubo_source():
    """The PRTSpec struct with the second lobe's bands and the maps' block after its members."""
    base = shader_specular.UBO_SOURCE
    assert base.endswith(" };\n")
    return base[: -len(" };\n")] + " vec4 bands2[8]; vec4 maps[5]; };\n"


def second_lobe(vertex):
    """The vertex shader with spec_occ2: the full transfer's occlusion for the lobe of bands2 (its
    sums in spec_occlusion's pass; the second channel of the pass's texel in the frame)."""
    out = []
    for line in vertex.split("\n"):
        out.append(line)
        if line.startswith("  seen += ") or line.startswith("  float open_ = "):
            out.append(line.replace("seen +=", "seen2 +=").replace("open_ =", "open2 =").replace("bands[", "bands2["))
        elif line == "  float seen = 0.0;":
            out.append("  float seen2 = 0.0;")
        elif line.startswith("  spec_occ = ") and "occ_tx" in line:
            out.append(line.replace("spec_occ =", "spec_occ2 =").replace(".r;", ".g;"))
        elif line.startswith("  spec_occ = "):
            out.append("  spec_occ2 = open2 > 1e-8 ? seen2 / open2 : 1.0;" if "seen" in line else "  spec_occ2 = 1.0;")
    assert sum(x.startswith("  spec_occ2 = ") for x in out) == 1
    return "\n".join(out)


def add_maps(info, vertex, fragment, texel=False):
    """Declare the maps' samplers and varying on `info`; -> (vertex, fragment) of the specular
    shader (textured: albedo_uv and albedo_texture.GLSL already in) reading the maps. texel: a
    texel bake, whose full-transfer occlusion is in the fragment (texel_occlusion)."""
    for slot, name in zip(SLOTS, NAMES):
        info.sampler(slot, "FLOAT_2D", f"{name}_tx")
    if texel:
        head, tail = fragment.split(texel_occlusion.FULL_FUNCTION, 1)
        body, rest = tail.split("\n}\n", 1)
        full = texel_occlusion.FULL_FUNCTION + second_lobe(body)
        fragment = "float spec_occ2 = 1.0;\n" + head + full + "\n}\n" + rest
    else:
        iface = gpu.types.GPUStageInterfaceInfo("prt_maps_iface")
        iface.smooth("FLOAT", "spec_occ2")
        info.vertex_out(iface)
    setup, occ = "void spec_setup()\n{\n", "clamp(spec_occ, 0.0, 1.0)"
    assert fragment.count(albedo_texture.GLSL) == 1 and setup in fragment and fragment.count(occ) == 1
    fragment = fragment.replace(occ, "clamp(mix(spec_occ, spec_occ2, spec_occ_t), 0.0, 1.0)")
    fragment = fragment.replace(setup, setup + "  spec_maps_setup();\n", 1)
    for axis, name in zip("xyz", ("spec_roughness", "spec_metallic", "spec_f0d")):
        fragment = fragment.replace(f"spec.material.{axis}", name)
    fragment = fragment.replace(albedo_texture.GLSL, albedo_texture.GLSL + GLSL, 1)
    return (vertex if texel else second_lobe(vertex)), fragment


_textures = {}  # (image pointer, channel, factor, input) -> (key, GPUTexture or None, note, (lo, hi))


@caches.on_clear
def clear_textures():
    _textures.clear()


def map_texture(item, index):
    """(GPUTexture or None, note, (smallest, largest value)) of a MapInput for input `index`."""
    ptr = (item.image.as_pointer(), item.channel, item.factor, index)
    key = albedo_texture.image_key(item.image)
    hit = _textures.get(ptr)
    if hit is not None and hit[0] == key:
        return hit[1:]
    limit = gpu.capabilities.max_texture_size_get()
    tex, span = None, (0.0, 0.0)
    if max(item.image.size) > limit:
        note = f"image '{item.image.name}' is larger than {limit} pixels, the GPU's limit"
    else:
        lower, upper = RANGES[index]
        values, note = map_pixels(item.image, item.channel, item.factor, upper, lower)
        if values is not None:
            tex = albedo_texture.upload(np.repeat(values[..., None], 3, axis=2))
            span = (float(values.min()), float(values.max()))
    _textures[ptr] = (key, tex, note, span)
    return tex, note, span


def slot_maps(obj, sources):
    """Per material slot of `obj` its scene.principled_maps.SlotMaps on the mesh, each on the UV
    map of the slot's albedo image when it has one (sources: albedo_source.slot_sources)."""
    out = []
    for i, slot in enumerate(obj.material_slots):
        src = sources[min(i, len(sources) - 1)] if sources else None
        albedo_uv = src.uv_map if src is not None and src.kind == "IMAGE" else None
        out.append(mesh_maps(slot.material, obj.data, albedo_uv))
    return out


def uv_maps(maps):
    """Per slot the UV map its maps are drawn on ("" without maps): gpu_cache's map_uvs."""
    return tuple(m.uv_map if m.any else "" for m in maps)


def slot_data(maps, params):
    """(the triple bind_slot takes, its roughness the first lobe's; the extra PRTSpec bytes:
    bands2, maps (per input (1, interpolation, extension) or 0, then (F0 per level of the constant
    IOR, the roughness span, the constant level)); per input its texture or None) of a slot with
    maps (params: principled_specular's); an input without a readable image keeps its constant."""
    roughness, metallic, f0 = params
    rows = np.zeros((13, 4))
    span = (roughness, roughness)
    textures = []
    for index, item in enumerate(maps.inputs):
        tex = None
        if item is not None:
            tex, _note, values = map_texture(item, index)
        textures.append(tex)
        if tex is None:
            continue
        rows[8 + index, :3] = (1.0, *item.sampling)
        if index == 0:
            span = values
    rows[12] = (maps.f0_per_level, *span, maps.level)
    rows[0:8] = _bands(span[1]).reshape(8, 4)
    return (span[0], metallic, f0), rows.astype(np.float32).tobytes(), textures


@functools.lru_cache(maxsize=64)
def _bands(roughness):
    """(32,) k_l of the lobe at `roughness`, as shader_specular's for the first lobe."""
    return occlusion.lobe_bands(float(max(roughness * roughness, 1e-3)), shader_specular.MAX_BAND_ORDER)


def bind(shader, textures):
    """Bind a slot's map textures (the white one for an input drawn as its constant)."""
    for name, tex in zip(NAMES, textures):
        shader.uniform_sampler(f"{name}_tx", tex if tex is not None else albedo_texture.white())


def notes(obj):
    """What the display says about `obj`'s Principled maps: each slot's fallbacks, and what reading
    its images said (once read)."""
    out = []
    for maps in slot_maps(obj, slot_sources(obj)):
        said = list(maps.notes)
        for index, item in enumerate(maps.inputs):
            hit = None if item is None else _textures.get((item.image.as_pointer(), item.channel, item.factor, index))
            if hit is not None and hit[0] == albedo_texture.image_key(item.image) and hit[2]:
                said.append(hit[2])
        out += [x for x in said if x not in out]
    return out
