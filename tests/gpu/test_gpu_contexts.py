"""render_view in another GPU context than the viewport's draw: the shadow maps and texel relights still bind.

Blender's OpenGL backend ties a framebuffer to the GPU context it was first bound in (every window
has its own; textures and buffers are shared between them, framebuffers are not): bound in another
one, it does not bind, and clearing it raises "Framebuffer is not bound". That is what a script
met calling render_view from a timer or an operator while the viewport had drawn the maps, in the
tick a bake ended (the maps are drawn again after a bake). Headless there is one context: the
framebuffers below follow the backend's rule against a context this test switches.
"""

import contextlib

import numpy as np
import pytest
from helpers.display_scenes import set_light
from helpers.shadow_scenes import render, set_suns, sky_light


class Contexts:
    """gpu.types.GPUFrameBuffer as the OpenGL backend treats it across contexts: the framebuffer
    takes the context of its first bind, and does not bind in any other."""

    def __init__(self, real):
        self.real, self.current = real, "viewport"
        outer = self

        class ContextFramebuffer:
            def __init__(self, *args, **kwargs):
                self._fb, self._context = real(*args, **kwargs), None

            def bind(self):
                if self._context is None:
                    self._context = outer.current
                return self._fb.bind() if self._context == outer.current else contextlib.nullcontext()

            def clear(self, **kwargs):
                if self._context != outer.current:
                    raise SystemError("Framebuffer is not bound")
                return self._fb.clear(**kwargs)

        self.Framebuffer = ContextFramebuffer


@pytest.fixture
def contexts(monkeypatch, gpu_ready):
    import gpu

    tracker = Contexts(gpu.types.GPUFrameBuffer)
    monkeypatch.setattr(gpu.types, "GPUFrameBuffer", tracker.Framebuffer)
    return tracker


def _sun(direction):
    from prt_addon.core.lights.extraction import Light

    d = np.asarray(direction, dtype=np.float64)
    return Light(direction=d / np.linalg.norm(d), power=np.array([3.0, 2.5, 2.0]), angle=0.01)


def test_shadow_maps_drawn_again_in_another_context_bind_there(bpy_module, ground_scene, contexts):
    from prt_addon.blender import caches

    scene, _ground = ground_scene
    set_suns(scene, [_sun((0.3, 0.2, 1.0))])
    render(scene)  # (the maps drawn in the viewport's context)
    box = bpy_module.data.objects["Box"]
    box.location.x += 0.5  # the casters moved: the maps are drawn again, as after a bake
    bpy_module.context.view_layer.update()
    contexts.current = "a script's timer"
    image = render(scene)
    caches.clear_all()  # (the lights' overrides too: set again)
    set_light(scene, sky_light())
    set_suns(scene, [_sun((0.3, 0.2, 1.0))])
    contexts.current = "fresh"
    expected = render(scene)
    np.testing.assert_array_equal(image, expected)
    assert np.ptp(image[..., 0]) > 0.5  # (a shadow in the picture, not an empty frame)


def test_a_texel_relight_drawn_again_in_another_context_binds_there(bpy_module, empty_scene, contexts):
    from prt_addon import api
    from prt_addon.blender import caches
    from prt_addon.blender.scene import lighting

    bpy = bpy_module
    scene = empty_scene
    bpy.ops.object.camera_add(location=(0.0, 0.0, 10.0), rotation=(0.0, 0.0, 0.0))
    scene.camera = bpy.context.object
    scene.camera.data.type = "ORTHO"
    scene.camera.data.ortho_scale = 4.0
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, -0.2, 0.5))
    light = np.zeros((9, 3))
    light[0], light[2] = 3.0, 1.5  # (a sky brighter above: the floor's texels differ)
    lighting.set_light_override(scene, light)
    scene.prt_display.albedo_source = "WHITE"
    api.bake([floor], order=3, samples=64, target="TEXELS", uv_map="UVMap", resolution=16)
    api.render_view(scene, 32, 32)  # (the relight drawn in the viewport's context)
    light[1] = 1.0  # the light changed: the texels are relit
    lighting.set_light_override(scene, light)
    contexts.current = "a script's timer"
    image = api.render_view(scene, 32, 32)
    caches.clear_all()  # (the light's override too: set again)
    lighting.set_light_override(scene, light)
    contexts.current = "fresh"
    np.testing.assert_array_equal(image, api.render_view(scene, 32, 32))
    assert image[..., 3].mean() > 0.9
