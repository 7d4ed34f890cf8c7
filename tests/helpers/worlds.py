"""Worlds for the tests: Blender's bundled HDRIs, worlds of known SH coefficients or images, a Mapping node, sunny images (bpy passed in or imported when called)."""

import math
import os

import numpy as np

from prt_addon.core.sh import basis as sh, projection


def bundled_hdri_path(name="forest"):
    """Path of one of Blender's bundled studio-light HDRIs (1024x512 EXR, CC0)."""
    import bpy

    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    path = os.path.join(folder, f"{name}.exr")
    assert os.path.isfile(path), path
    return path


SQRT_4PI = math.sqrt(4.0 * math.pi)


def new_world(bpy, scene, color=(1.0, 1.0, 1.0), strength=1.0):
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:  # Blender 4.x: new worlds have no nodes
        world.use_nodes = True
    scene.world = world
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    return world


def float_image(bpy, name, rgb):
    rgb = np.asarray(rgb, dtype=np.float64)
    height, width = rgb.shape[:2]
    image = bpy.data.images.new(name, width, height, float_buffer=True)
    rgba = np.concatenate([rgb, np.ones((height, width, 1))], axis=2).astype(np.float32)
    image.pixels.foreach_set(rgba.ravel())
    return image


def use_image(world, image, strength=1.0):
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    background = tree.nodes["Background"]
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = strength
    return env


def add_mapping(world, env, euler=(0.0, 0.0, 0.0), vector_type="POINT"):
    tree = world.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.vector_type = vector_type
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    mapping.inputs["Rotation"].default_value = euler
    return mapping


def known_coeffs(order=6, seed=3):
    rng = np.random.default_rng(seed)
    c = 0.3 * rng.normal(size=(order * order, 3))
    c[0] = 8.0  # keeps the function positive, so the pixel repair never changes it
    return c


def image_of(c, height, width, rotation_3x3=None):
    """Pixels of f(R d) at the pixel centres d (R = identity by default)."""
    d = projection.pixel_directions(height, width).reshape(-1, 3)
    if rotation_3x3 is not None:
        d = d @ np.asarray(rotation_3x3).T
    return sh.evaluate(c, d).reshape(height, width, 3)


def sunny_image(height, width, sun=(0.4, 0.6), power=400.0):
    """A smooth sky (known SH coefficients) with a small very bright patch at (u, v)."""
    rgb = image_of(known_coeffs(4), height, width)
    size = max(2, width // 64)
    row, col = int(sun[1] * height), int(sun[0] * width)
    rgb[row : row + size, col : col + size] = np.array([1.0, 0.9, 0.7]) * power
    return rgb


def image_world(bpy, scene, rgb, strength=1.0, euler=None):
    world = new_world(bpy, scene)
    env = use_image(world, float_image(bpy, "sky", rgb), strength)
    mapping = add_mapping(world, env, euler) if euler is not None else None
    return world, mapping


Y0 = 1.0 / math.sqrt(4.0 * math.pi)
