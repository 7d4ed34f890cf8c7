"""A material's Principled specular constants: roughness, metallic and the dielectric F0."""

from ...core.specular import brdf
from .materials import active_output


def _value(node, name, default):
    sock = node.inputs.get(name)
    if sock is None or not hasattr(sock, "default_value"):
        return default
    # A linked socket is read as its constant here; the display reads images per pixel (principled_maps).
    return float(sock.default_value)


def principled_specular(material):
    """(roughness, metallic, dielectric F0) of the Principled BSDF feeding the material's active
    output, clamped to their ranges; None for any other surface (drawn diffuse only)."""
    output = active_output(material) if material is not None else None
    if output is None or not output.inputs["Surface"].is_linked:
        return None
    node = output.inputs["Surface"].links[0].from_node
    if node.bl_idname != "ShaderNodeBsdfPrincipled" or node.mute:
        return None
    roughness = min(max(_value(node, "Roughness", 0.5), 0.0), 1.0)
    metallic = min(max(_value(node, "Metallic", 0.0), 0.0), 1.0)
    level = max(_value(node, "Specular IOR Level", 0.5), 0.0)
    f0 = float(brdf.dielectric_f0(_value(node, "IOR", 1.5), level))
    return roughness, metallic, f0
