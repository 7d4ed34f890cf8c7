"""The 3D Views redraw when a display switch is set from Python, not only from the sidebar."""

import types

import pytest


@pytest.fixture
def redraw_count(monkeypatch, addon):
    from prt_addon.blender.display import redraw

    calls = []
    monkeypatch.setattr(redraw, "tag_redraw", lambda: calls.append(1))
    return calls


@pytest.mark.parametrize(("group", "name"), [("prt", "show_display"), ("prt_display", "show_light_directions")])
def test_a_display_switch_set_from_python_tags_the_views(empty_scene, redraw_count, group, name):
    settings = getattr(empty_scene, group)
    setattr(settings, name, not getattr(settings, name))
    assert len(redraw_count) == 1
    setattr(settings, name, not getattr(settings, name))
    assert len(redraw_count) == 2


def test_tag_redraw_tags_every_3d_view_of_every_window_and_nothing_else(monkeypatch, addon):
    from prt_addon.blender.display import redraw

    tagged = []

    def area(kind):
        return types.SimpleNamespace(type=kind, tag_redraw=lambda: tagged.append(kind))

    screens = [[area("VIEW_3D"), area("PROPERTIES")], [area("OUTLINER"), area("VIEW_3D"), area("VIEW_3D")]]
    windows = [types.SimpleNamespace(screen=types.SimpleNamespace(areas=areas)) for areas in screens]
    context = types.SimpleNamespace(window_manager=types.SimpleNamespace(windows=windows))
    monkeypatch.setattr(redraw, "bpy", types.SimpleNamespace(context=context))
    redraw.tag_redraw()
    assert tagged == ["VIEW_3D"] * 3
