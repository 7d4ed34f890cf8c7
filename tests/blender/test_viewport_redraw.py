"""The 3D Views redraw when a display switch is set from Python, not only from the sidebar."""

import types

import bpy
import pytest


@pytest.fixture
def redraw_count(monkeypatch, addon):
    from prt_addon.blender.display import switches

    calls = []
    monkeypatch.setattr(switches, "tag_redraw", lambda: calls.append(1))
    return calls


@pytest.mark.parametrize(("group", "name"), [("prt", "show_display"), ("prt_display", "show_light_directions")])
def test_a_display_switch_set_from_python_tags_the_views_at_the_next_look(empty_scene, redraw_count, group, name):
    from prt_addon.blender.display import switches

    settings = getattr(empty_scene, group)
    assert not switches.look([empty_scene])  # the first look only records
    setattr(settings, name, not getattr(settings, name))
    assert switches.look([empty_scene]) and len(redraw_count) == 1
    assert not switches.look([empty_scene]) and len(redraw_count) == 1  # nothing changed since
    setattr(settings, name, not getattr(settings, name))
    empty_scene.prt_bake.order = empty_scene.prt_bake.order + 1  # (not a display switch)
    assert switches.look([empty_scene]) and len(redraw_count) == 2
    empty_scene.prt_bake.order = empty_scene.prt_bake.order - 1
    assert not switches.look([empty_scene]) and len(redraw_count) == 2


def test_the_switch_timer_runs_while_enabled_and_no_switch_has_an_update_callback(addon):
    from prt_addon.blender.display import switches

    assert bpy.app.timers.is_registered(switches._poll)
    assert switches._poll() == switches.POLL_INTERVAL
    # (bpy 4.2 as a module crashes at exit after uninstalling an extension with update callbacks)
    from prt_addon.blender.registration import MODULES

    classes = [cls for module in MODULES for cls in getattr(module, "CLASSES", ())]

    callbacks = [
        f"{cls.__name__}.{name}"
        for cls in classes
        for name, prop in getattr(cls, "__annotations__", {}).items()
        if any(key in getattr(prop, "keywords", {}) for key in ("update", "get", "set"))
    ]
    assert callbacks == []
    assert any("show_display" in getattr(cls, "__annotations__", {}) for cls in classes)


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
