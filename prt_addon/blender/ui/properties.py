"""The add-on's settings stored on the scene (saved with the .blend file), with their tooltips.

scene.prt (PRT_PG_scene), scene.prt_world (the world projection's settings and record; the
coefficients themselves are ID-property arrays, see world.projection), scene.prt_bake and
scene.prt_display.
"""

import bpy

from ...core.lights.extraction import MAX_LIGHTS
from ..bake.presets import CYCLES_DIFFUSE_BOUNCES
from ..bake.settings import ADAPTIVE, MAX_BOUNCES, MAX_ORDER, MAX_RESOLUTION, MIN_SAMPLES
from ..world.projection import MAX_ORDER as MAX_WORLD_ORDER


class PRT_PG_scene(bpy.types.PropertyGroup):
    """Root of the add-on's per-scene settings; feature modules add their own groups beside it."""

    show_display: bpy.props.BoolProperty(
        name="Show PRT",
        description="Draw baked objects with PRT lighting in the 3D View",
        default=True,
    )


class PRT_PG_world(bpy.types.PropertyGroup):
    order: bpy.props.IntProperty(
        name="Order",
        description="SH order of the world lighting (order**2 coefficients per colour channel)",
        default=8,
        min=1,
        max=MAX_WORLD_ORDER,
        soft_max=16,
    )
    stored_order: bpy.props.IntProperty(name="Stored Order", description="0: nothing stored", default=0)
    source_kind: bpy.props.StringProperty(name="Source", description="IMAGE, COLOR or RENDER")
    world_name: bpy.props.StringProperty(name="World", description="The world that was projected")
    source_node: bpy.props.StringProperty(name="Node", description="The world node whose light was projected")
    image_name: bpy.props.StringProperty(name="Image", description="The image that was projected")
    image_size: bpy.props.IntVectorProperty(name="Image Size", size=2, description="Width and height of that image")
    projected_size: bpy.props.IntVectorProperty(
        name="Projected Size", size=2, description="Width and height of the pixels projected"
    )
    mapping_node: bpy.props.StringProperty(name="Mapping Node", description="The Mapping node that turns the world")
    mapping_type: bpy.props.StringProperty(name="Mapping Type", description="That Mapping node's type")
    mapping_rotation: bpy.props.FloatVectorProperty(
        name="Mapping Rotation", size=3, subtype="EULER", description="That Mapping node's rotation at projection"
    )
    rotation_matrix: bpy.props.FloatVectorProperty(
        name="SH Rotation",
        description="Q, row-major: world coefficients = rotate(stored coefficients, Q)",
        size=9,
        default=(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
    )
    seconds: bpy.props.FloatProperty(name="Time", unit="TIME_ABSOLUTE", description="How long the projection took")
    truncation: bpy.props.FloatProperty(
        name="Truncation",
        description="Fraction of the L2 luminance energy of the world beyond the stored order",
        subtype="FACTOR",
    )
    diffuse_truncation: bpy.props.FloatProperty(
        name="Diffuse Truncation",
        description="Fraction of the L2 luminance energy of unshadowed diffuse shading beyond the stored order",
        subtype="FACTOR",
    )
    split_lights: bpy.props.BoolProperty(
        name="Split Lights",
        description="At the next projection, take the world's compact bright sources (a sun, lamps) out "
        "of the SH as lights with their own shadows; SH of any order cannot hold them",
        default=True,
    )
    auto_threshold: bpy.props.BoolProperty(
        name="Auto Threshold",
        description="Choose the light threshold from the image: the larger of 3 times its mean luminance and "
        "the level that keeps the bright texels within 10 % of the sphere",
        default=True,
    )
    light_threshold: bpy.props.FloatProperty(
        name="Threshold",
        description="Luminance above which texels become lights, when Auto Threshold is off (0 is automatic too)",
        default=0.0,
        min=0.0,
        soft_max=1000.0,
    )
    max_lights: bpy.props.IntProperty(
        name="Max Lights",
        description="At most this many lights, the most powerful bright regions; the others stay in the SH",
        default=4,
        min=0,
        max=MAX_LIGHTS,
    )
    stored_split: bpy.props.BoolProperty(
        name="Split Used",
        description="Whether the stored projection split lights off the world",
    )
    light_count: bpy.props.IntProperty(
        name="Lights",
        description="Number of lights split off at the last projection",
        default=0,
    )
    light_share: bpy.props.FloatProperty(
        name="Light Share",
        description="Fraction of the world's power (luminance) held by the split lights",
        subtype="FACTOR",
    )
    strongest_elevation: bpy.props.FloatProperty(
        name="Strongest Elevation",
        description="Elevation of the strongest light above the horizon (Mapping rotation of the projection)",
        subtype="ANGLE",
    )
    message: bpy.props.StringProperty(name="Notes", description="What the projection reported")
    token: bpy.props.StringProperty(name="Token", description="Changes at every projection")


class PRT_PG_bake_settings(bpy.types.PropertyGroup):
    order: bpy.props.IntProperty(
        name="Order",
        description="SH order n: n*n transfer coefficients per vertex",
        default=4,
        min=1,
        max=MAX_ORDER,
    )
    samples: bpy.props.IntProperty(
        name="Samples",
        description="Directions of the shared direction set (rays per vertex)",
        default=256,
        min=MIN_SAMPLES,
        soft_min=16,
        max=65536,
    )
    direction_set: bpy.props.EnumProperty(
        name="Directions",
        description="How the shared directions (one ray per vertex each) are spread over the sphere",
        items=[
            ("FIBONACCI", "Fibonacci", "Spherical Fibonacci set, randomly rotated (most accurate)"),
            ("STRATIFIED", "Stratified", "Jittered equal-area strata"),
            ("UNIFORM", "Uniform", "Independent uniform random directions"),
        ],
        default="FIBONACCI",
    )
    seed: bpy.props.IntProperty(name="Seed", description="Seed of the direction set", default=0, min=0)
    bounces: bpy.props.IntProperty(
        name="Bounces",
        description=(
            "Diffuse reflections between the world and the surface (as Cycles' Light Paths > Max Bounces > "
            "Diffuse, whose default is 4): light bounced off other surfaces, coloured by their materials. "
            "0: direct light only (rooms come out dark)"
        ),
        default=CYCLES_DIFFUSE_BOUNCES,
        min=0,
        max=MAX_BOUNCES,
    )
    target: bpy.props.EnumProperty(
        name="Target",
        description="Where the transfer is baked and stored",
        items=[
            ("VERTICES", "Vertices", "Per vertex, in colour attributes: for dense meshes"),
            ("TEXELS", "Texels", "Per texel of a lightmap UV map, in a float image: for low-poly meshes"),
            (
                "AUTO",
                "Auto",
                "Texels for meshes too coarse for their size (fewer vertices than a texel per 4 x 4), else vertices",
            ),
        ],
        default="VERTICES",
    )
    uv_map: bpy.props.StringProperty(
        name="UV Map",
        description=(
            "The UV map texel bakes use; empty: a UV map whose name contains 'Lightmap', else a new one "
            "('PRT Lightmap', by Smart UV Project; the other UV maps are not changed)"
        ),
        default="",
    )
    resolution: bpy.props.IntProperty(
        name="Resolution",
        description="Texels per side of each object's lightmap; 0: from the texel density",
        default=0,
        min=0,
        max=MAX_RESOLUTION,
    )
    texel_density: bpy.props.FloatProperty(
        name="Texels per Metre",
        description="Lightmap texels per metre of surface when Resolution is 0",
        default=20.0,
        min=0.1,
        soft_max=200.0,
    )
    texel_adaptive: bpy.props.FloatProperty(
        name="Adaptive",
        description="Texels: trace a lattice of every 4th texel and interpolate the blocks whose corners agree "
        "within this relative difference (edges, contacts and shadows are traced); 0 traces every texel",
        default=ADAPTIVE,
        min=0.0,
        max=1.0,
        step=1,
    )
    shadows: bpy.props.BoolProperty(
        name="Shadows",
        description="Trace visibility (shadowed transfer); off: cosine only",
        default=True,
    )
    self_shadow_only: bpy.props.BoolProperty(
        name="Self-Shadow Only",
        description="Only the object itself occludes (no other objects)",
        default=False,
    )
    backend: bpy.props.EnumProperty(
        name="Backend",
        description="Which ray tracer computes the shadows: Embree (fast) or Blender's BVH tree (fallback)",
        items=[
            ("AUTO", "Auto", "Embree when available, else Blender's BVH tree"),
            ("EMBREE", "Embree", "embreex (Embree 4), multi-threaded"),
            ("BVHTREE", "BVH Tree", "mathutils.bvhtree, single-threaded and slower"),
        ],
        default="AUTO",
    )
    last_report: bpy.props.StringProperty(
        name="Last Report", default="", options={"SKIP_SAVE"}, description="The last bake's report (JSON)"
    )


class PRT_PG_display(bpy.types.PropertyGroup):
    # No Python get/set/update callbacks here: with them, bpy 4.2 (as a module) crashes at exit
    # after unregister. The draw reads these every redraw; the batch cache key includes them.
    albedo_source: bpy.props.EnumProperty(
        name="Albedo",
        description="The surface colour the lighting is multiplied by in the viewport",
        items=[
            ("MATERIAL", "Material", "Base colour of each material slot"),
            ("ATTRIBUTE", "Color Attribute", "A colour attribute of the mesh"),
            ("WHITE", "White", "No albedo: radiance only"),
        ],
        default="MATERIAL",
    )
    albedo_attribute: bpy.props.StringProperty(
        name="Attribute",
        description="Colour attribute used as albedo (empty: the mesh's active colour attribute)",
        default="",
    )
    specular: bpy.props.BoolProperty(
        name="Specular",
        description="Draw Principled materials' reflections: the sky prefiltered at their roughness and "
        "the split lights' highlights (Roughness, Metallic and Specular IOR Level as constants or from image "
        "textures, IOR as a constant); the glTF export carries them for the web viewer. Off by default",
        default=False,
    )
    show_light_directions: bpy.props.BoolProperty(
        name="Light Directions",
        description="Draw a line from the 3D cursor toward each light split off the world, in the light's "
        "colour, with a circle of its angular size at the tip; it turns with the Lighting Rotation",
        default=False,
    )


CLASSES = [PRT_PG_scene, PRT_PG_world, PRT_PG_bake_settings, PRT_PG_display]

_POINTERS = (
    ("prt", PRT_PG_scene),
    ("prt_world", PRT_PG_world),
    ("prt_bake", PRT_PG_bake_settings),
    ("prt_display", PRT_PG_display),
)


def register_extra():
    for name, group in _POINTERS:
        setattr(bpy.types.Scene, name, bpy.props.PointerProperty(type=group))


def unregister_extra():
    for name, _group in _POINTERS:
        if hasattr(bpy.types.Scene, name):
            delattr(bpy.types.Scene, name)
