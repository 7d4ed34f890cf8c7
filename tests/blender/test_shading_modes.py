"""The overlay draws in Solid shading only, and the PRT panel says so in the other modes."""

import types

import pytest

MODES = ["SOLID", "WIREFRAME", "MATERIAL", "RENDERED"]


def _space(kind):
    return types.SimpleNamespace(shading=types.SimpleNamespace(type=kind))


@pytest.mark.parametrize("kind", MODES)
def test_the_draw_handler_draws_in_solid_only(bpy_module, empty_scene, monkeypatch, kind):
    from prt_addon.blender.display import draw

    looked = []
    monkeypatch.setattr(draw, "baked_objects", lambda *args: looked.append(args) or [])
    context = types.SimpleNamespace(
        scene=empty_scene, view_layer=empty_scene.view_layers[0], space_data=_space(kind), region_data=object()
    )
    draw.draw_viewport(context)
    assert bool(looked) == (kind == "SOLID")  # (the objects are looked for only where they are drawn)


@pytest.mark.parametrize("kind", MODES)
def test_the_panel_says_when_the_shading_hides_the_overlay(bpy_module, empty_scene, kind):
    from prt_addon.blender.ui.panels import shading_note

    note = shading_note(empty_scene, _space(kind))
    expected = {
        "SOLID": None,
        "WIREFRAME": "Not drawn in Wireframe shading: PRT draws in Solid",
        "MATERIAL": "Not drawn in Material Preview shading: PRT draws in Solid",
        "RENDERED": "Not drawn in Rendered shading: PRT draws in Solid",
    }
    assert note == expected[kind]
    empty_scene.prt.show_display = False  # (nothing to say when the display is off)
    assert shading_note(empty_scene, _space(kind)) is None
