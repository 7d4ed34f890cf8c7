"""GLSL of a texel bake's specular occlusion: the full transfer read per pixel at the lightmap UV.

A texel bake's transfer is a texture (scene.texel_storage: tile g of the image at column
g % tiles_x, row g // tiles_x), so what a vertex bake sums per vertex is summed here per pixel:
the full transfer's lobe-weighted visibility (shader_specular.occlusion_lines, its vertex form
run in the fragment on the coefficients looked up at the pixel, with the interpolated position
and normal), at every roughness (the cones of bands 0 and 1, and the vertex bakes' blend from
them, are further from the lobe integral and from Cycles: docs/specular.md). Each tile is
looked up with the GPU's bilinear filter inside the tile, (clamp(uv res, 1/2, res - 1/2) + tile
origin) / size: the clamp-to-edge bilinear lookup of the texel relight (shader._TEXEL_FUNCTION)
and of core.transfer.lightmap.bilinear. Faces seen from behind (an open mesh's back side) keep
the open transfer: occlusion 1.
"""

from . import shader_specular

TILES_SLOT = 11  # sampler slot (0 the relit radiance, 1 and 2 shadow maps, 3 and 4 the sky and
# table, 5 the albedo image, 6 to 8 and 10 the Principled maps, 9 the colour table)

FULL_FUNCTION = "void texel_full_occlusion()\n{\n"
GLOBALS = f"vec4 spec_vis = vec4({shader_specular.Y0}, 0.0, 0.0, 0.0);\nfloat spec_occ = 1.0;\n"

_LOOKUP = """
vec4 texel_tile(int g)
{
  int res = texel_grid.x;
  vec2 p = clamp(texel_uv * float(res), vec2(0.5), vec2(float(res) - 0.5));
  p += vec2(float((g % texel_grid.y) * res), float((g / texel_grid.y) * res));
  return texture(texel_tiles_tx, p / vec2(textureSize(texel_tiles_tx, 0)));
}
"""


def _full_function(count):
    """GLSL of texel_full_occlusion(): the vertex path's full-transfer lines (ATTR form: prt_tK,
    prt_pos, prt_nrm; they set spec_occ) on the pixel's coefficients, position and normal."""
    body = shader_specular.occlusion_lines("ATTR", count)
    used = sorted({int(x.split("[")[0]) for x in body.split("prt_t")[1:]})
    tiles = "".join(f"  vec4 prt_t{k} = texel_tile({k});\n" for k in used)
    return FULL_FUNCTION + "  vec3 prt_pos = spec_pos;\n  vec3 prt_nrm = spec_nrm;\n" + tiles + body + "}\n"


def add_occlusion(info, fragment, count, back):
    """Declare the tiles' sampler on `info`; -> the fragment with spec_occ summed per pixel and
    used at every roughness (count: the direct transfer's vec4s per texel; back: the mesh has a
    back side, whose faces keep occlusion 1). The caller puts GLOBALS before the specular's
    functions."""
    info.sampler(TILES_SLOT, "FLOAT_2D", "texel_tiles_tx")
    main, setup = "void main()\n{\n", "  spec_setup();\n"
    weight = f"clamp((spec.material.x - {shader_specular.ROUGH_FROM}) / {shader_specular.ROUGH_SPAN}, 0.0, 1.0)"
    assert fragment.count(main) == 1 and fragment.count(setup) == 1 and fragment.count(weight) == 1
    fragment = fragment.replace(weight, "1.0", 1)  # (the full transfer, not the cones, at every roughness)
    read = "  if (prt_front()) {\n    texel_full_occlusion();\n  }\n" if back else "  texel_full_occlusion();\n"
    fragment = fragment.replace(main, _LOOKUP + _full_function(count) + main, 1)
    return fragment.replace(setup, setup + read, 1)
