"""Everything about the World node tree: what feeds the Background, and its Mapping node.

One resolution of the node tree (`analyse_world`, through reroutes, muted nodes and links) is
used by the projection, the live rotation of the lighting, the display and the rotation control,
so they all follow what Cycles shows.

Measured against Cycles (tests/cycles/test_world_cycles.py): with a Mapping rotation R (Euler XYZ,
R = Rz Ry Rx), the world seen along D is image(R D) for vector types POINT, VECTOR and NORMAL and
image(R^-1 D) for TEXTURE; so world coefficients = rotate(image coefficients, Q) with Q = R^T
(POINT, VECTOR, NORMAL) or Q = R (TEXTURE), since rotate(c, Q) gives f(Q^-1 w).
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ...core.sh import rotation


class WorldError(ValueError):
    """The world cannot be projected; the message is meant for the user."""


@dataclass
class MappingInfo:
    node_name: str
    vector_type: str
    euler: tuple

    def sh_rotation(self):
        return mapping_sh_rotation(self.vector_type, self.euler)


@dataclass
class WorldSource:
    kind: str  # "IMAGE", "COLOR" or "RENDER"
    world_name: str
    node_name: str = ""
    image: object = None
    color: object = None
    strength: float = 1.0
    mapping: MappingInfo = None
    reason: str = ""


def mapping_sh_rotation(vector_type, euler):
    """Q such that world coefficients = rotation.rotate(image coefficients, Q) (measured)."""
    r = rotation.euler_xyz_matrix(euler)
    return r if vector_type == "TEXTURE" else r.T


def _from_link(socket):
    """The link feeding `socket`, through reroutes; None if unlinked or muted."""
    while socket.is_linked:
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            continue
        return link
    return None


def _use_nodes(world):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return bool(world.use_nodes) and world.node_tree is not None


def _render_source(world, node, reason):
    return WorldSource("RENDER", world.name, node_name=node.name if node else "", reason=reason)


def _mapping_info(world, env, link):
    """MappingInfo of a Mapping node feeding env's Vector, or a RENDER source if unrepresentable."""
    mapping = link.from_node
    if mapping.bl_idname != "ShaderNodeMapping":
        return _render_source(world, env, f"the Vector of '{env.name}' comes from '{link.from_node.name}'")
    source = _from_link(mapping.inputs["Vector"])
    if mapping.mute:  # a muted node passes its Vector input through: Generated is no rotation
        if source is None or (
            source.from_node.bl_idname == "ShaderNodeTexCoord" and source.from_socket.identifier == "Generated"
        ):
            return None
        return _render_source(
            world,
            env,
            f"the muted Mapping node '{mapping.name}' passes on another vector than Texture Coordinate > Generated",
        )
    if (
        source is None
        or source.from_node.bl_idname != "ShaderNodeTexCoord"
        or source.from_socket.identifier != "Generated"
    ):
        return _render_source(
            world, env, f"the Mapping node '{mapping.name}' is not fed by Texture Coordinate > Generated"
        )
    vector_type = mapping.vector_type
    sockets = {s.name: s for s in mapping.inputs}
    for name in ("Location", "Rotation", "Scale"):
        if name in sockets and sockets[name].enabled and _from_link(sockets[name]) is not None:
            return _render_source(world, env, f"the {name} of Mapping node '{mapping.name}' is linked")
    problems = []
    if vector_type in ("POINT", "TEXTURE"):
        location = np.array(sockets["Location"].default_value, dtype=np.float64)
        if np.any(location != 0.0):
            problems.append(f"location {tuple(np.round(location, 4))}")
    scale = np.array(sockets["Scale"].default_value, dtype=np.float64)
    # The Environment Texture normalises its vector, so a uniform positive scale changes nothing.
    if not (np.all(scale > 0.0) and np.ptp(scale) <= 1e-6 * scale.max()):
        problems.append(f"scale {tuple(np.round(scale, 4))}")
    if problems:
        return _render_source(
            world,
            env,
            f"the Mapping node '{mapping.name}' has a {' and a '.join(problems)} that an SH rotation cannot represent",
        )
    euler = tuple(float(a) for a in sockets["Rotation"].default_value)
    return MappingInfo(mapping.name, vector_type, euler)


def analyse_world(scene):
    """What the scene's world is made of: a WorldSource, or WorldError if there is no light."""
    if scene.world is None:
        raise WorldError(f"Scene '{scene.name}' has no World: add one in the World properties")
    return _analyse(scene.world)


def analyse_world_tree(world):
    """analyse_world for a World datablock; None where analyse_world raises (no light)."""
    if world is None:
        return None
    try:
        return _analyse(world)
    except WorldError:
        return None


def _analyse(world):
    if not _use_nodes(world):
        color = np.array(world.color, dtype=np.float64)[:3]
        return WorldSource("COLOR", world.name, color=color)
    tree = world.node_tree
    output = tree.get_output_node("CYCLES")
    if output is None:
        raise WorldError(f"World '{world.name}' has no active World Output node: it emits no light")
    link = _from_link(output.inputs["Surface"])
    if link is None:
        raise WorldError(f"Nothing is connected to the Surface of World '{world.name}': it emits no light")
    background = link.from_node
    if background.bl_idname != "ShaderNodeBackground" or background.mute:
        return _render_source(world, background, f"the world surface is '{background.name}', not a Background")
    if _from_link(background.inputs["Strength"]) is not None:
        return _render_source(world, background, f"the Strength of '{background.name}' is linked")
    strength = float(background.inputs["Strength"].default_value)
    if not math.isfinite(strength) or strength < 0.0:
        raise WorldError(f"Background '{background.name}' has a strength of {strength}: it must be >= 0")
    color_link = _from_link(background.inputs["Color"])
    if color_link is None:
        color = np.array(background.inputs["Color"].default_value, dtype=np.float64)[:3]
        return WorldSource("COLOR", world.name, node_name=background.name, color=color, strength=strength)
    env = color_link.from_node
    if (
        env.bl_idname != "ShaderNodeTexEnvironment"
        or env.mute
        or color_link.from_socket.identifier != "Color"
        or env.projection != "EQUIRECTANGULAR"
    ):
        return _render_source(world, env, f"the Background colour comes from '{env.name}'")
    if env.image is None:
        raise WorldError(f"Environment Texture '{env.name}' has no image")
    if env.image.source not in ("FILE", "GENERATED"):
        return _render_source(world, env, f"image '{env.image.name}' is a {env.image.source.lower()}")
    mapping = None
    vector_link = _from_link(env.inputs["Vector"])
    if vector_link is not None:
        if vector_link.from_node.bl_idname == "ShaderNodeTexCoord":
            if vector_link.from_socket.identifier != "Generated":
                return _render_source(world, env, f"the Vector of '{env.name}' is not Generated coordinates")
        else:
            mapping = _mapping_info(world, env, vector_link)
            if isinstance(mapping, WorldSource):
                return mapping
    return WorldSource("IMAGE", world.name, node_name=env.name, image=env.image, strength=strength, mapping=mapping)


def _lighting_environment(world):
    """The equirectangular Environment Texture feeding the world's Background colour, or None."""
    if world is None or not _use_nodes(world):
        return None
    output = world.node_tree.get_output_node("CYCLES")
    link = None if output is None else _from_link(output.inputs["Surface"])
    if link is None:
        return None
    background = link.from_node
    if background.bl_idname != "ShaderNodeBackground" or background.mute:
        return None
    color_link = _from_link(background.inputs["Color"])
    env = None if color_link is None else color_link.from_node
    if env is None or env.bl_idname != "ShaderNodeTexEnvironment" or env.mute or env.projection != "EQUIRECTANGULAR":
        return None
    return env


def find_environment_node(world):
    """The Environment Texture that lights the world (the one feeding its Background), else the
    first one in the tree, else None."""
    env = _lighting_environment(world)
    if env is not None or world is None or world.node_tree is None:
        return env
    for node in world.node_tree.nodes:
        if node.bl_idname == "ShaderNodeTexEnvironment":
            return node
    return None


def find_mapping_node(world):
    """The Mapping node (not muted) feeding the Environment Texture's Vector input, through
    reroutes, or None."""
    env = find_environment_node(world)
    link = None if env is None else _from_link(env.inputs["Vector"])
    if link is None:
        return None
    node = link.from_node
    return node if node.bl_idname == "ShaderNodeMapping" and not node.mute else None


def live_sh_rotation(world):
    """Q (3x3) with world coefficients = rotate(image coefficients, Q) for the world's node tree
    as it is now, resolved by the same rules as the projection (analyse_world); None when the
    world is not lit by an Environment Texture through a representable Mapping node."""
    env = _lighting_environment(world)
    if env is None:
        return None
    vector_link = _from_link(env.inputs["Vector"])
    if vector_link is None:
        return np.eye(3)
    if vector_link.from_node.bl_idname == "ShaderNodeTexCoord":
        return np.eye(3) if vector_link.from_socket.identifier == "Generated" else None
    mapping = _mapping_info(world, env, vector_link)
    if isinstance(mapping, WorldSource):
        return None
    return np.eye(3) if mapping is None else mapping.sh_rotation()


def ensure_mapping_node(world):
    """The Mapping node in front of the Environment Texture, created (Texture Coordinate
    Generated -> Mapping (Point) -> Vector) if needed. None when the world has no Environment
    Texture."""
    node = find_mapping_node(world)
    if node is not None:
        return node
    env = find_environment_node(world)
    if env is None:
        return None
    tree = world.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    coords.location = (env.location.x - 500, env.location.y)
    mapping.location = (env.location.x - 300, env.location.y)
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    return mapping


def mapping_rotation_euler(world):
    """The Mapping node's rotation (radians, XYZ Euler) or (0, 0, 0) without a node."""
    node = find_mapping_node(world)
    if node is None:
        return (0.0, 0.0, 0.0)
    return tuple(node.inputs["Rotation"].default_value)


def set_mapping_rotation_euler(world, euler):
    """The single place where the sidebar's lighting rotation is written into the world."""
    node = ensure_mapping_node(world)
    if node is None:
        return False
    node.inputs["Rotation"].default_value = tuple(float(a) for a in euler)
    return True
