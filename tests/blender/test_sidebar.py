"""The PRT tab's words and presets: the one-line result, the full report, the bake presets."""

from helpers.panels import RecordingLayout


def test_presets_set_order_and_samples_and_custom_is_recognised(bpy_module, empty_scene):
    from prt_addon.blender.bake.presets import PRESETS, preset_of

    bpy = bpy_module
    for key, (_label, _tip, order, samples, bounces) in PRESETS.items():
        assert bpy.ops.prt.bake_preset(preset=key) == {"FINISHED"}
        settings = empty_scene.prt_bake
        assert (settings.order, settings.samples, settings.bounces) == (order, samples, bounces)
        assert preset_of(settings.order, settings.samples, settings.bounces) == key
    empty_scene.prt_bake.samples = 300
    assert preset_of(empty_scene.prt_bake.order, empty_scene.prt_bake.samples, 4) == "CUSTOM"
    # A new scene's Bake panel (the properties' defaults) is the "Good" preset, with Cycles' own
    # default count of diffuse bounces; the API keeps Good's order and samples and bakes the direct
    # transfer unless asked for bounces (its callers compare with Cycles' DIRECT pass).
    import inspect

    from prt_addon import api

    parameters = inspect.signature(api.bake).parameters
    assert preset_of(parameters["order"].default, parameters["samples"].default, 4) == "GOOD"
    assert parameters["bounces"].default == 0
    properties = empty_scene.prt_bake.bl_rna.properties
    defaults = (properties["order"].default, properties["samples"].default, properties["bounces"].default)
    assert preset_of(*defaults) == "GOOD"
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with_cycles = bpy.context.scene
    with_cycles.render.engine = "CYCLES"
    assert with_cycles.cycles.diffuse_bounces == defaults[2]


def test_result_line_and_report_speak_plainly_and_fit(bpy_module):
    from prt_addon.blender.bake.settings import BakeReport
    from prt_addon.blender.ui.bake_panel import result_line

    report = BakeReport(
        ok=True,
        objects=["Suzanne", "Ground"],
        backend="EMBREE",
        seconds=0.561,
        rays_traced=1_491_273,
        rays_skipped=1_498_512,
        skipped_below_horizon=1_400_000,
        skipped_unoccludable=98_512,
        order=4,
        samples=256,
        direction_set="FIBONACCI",
        error_estimate_relative=0.0312,
    )
    assert result_line(report) == "0.56 s - 1.5 M rays - about 3 % noise"
    lines = report.report_lines()
    assert lines[0] == "Baked 2 object(s): Suzanne, Ground"
    assert any("1,491,273" in line for line in lines)
    assert not any("|t|" in line or "point domain" in line for line in lines)
    quiet = BakeReport(ok=True, objects=["a"], seconds=0.1, rays_traced=10, error_estimate_relative=0.004)
    assert result_line(quiet).endswith("under 1 % noise (0.40)")


def test_long_labels_wrap_to_the_region_width(bpy_module):
    from prt_addon.blender.ui import sidebar

    class Region:
        width = 260  # about the default sidebar width at 100 % scale

    class Context:
        region = Region()

    width = sidebar.line_width(Context())
    assert 20 <= width <= 40
    text = "Fast ray tracing (Embree) is not available here: baking is about 30 to 40 times slower"
    log = []
    sidebar.wrapped_label(RecordingLayout(log), Context(), text)
    lines = [entry[1] for entry in log]
    assert len(lines) > 1 and " ".join(lines) == text
    assert all(len(line) <= width for line in lines)


def draw_panel(panel_class, scene):
    import types

    log = []
    context = types.SimpleNamespace(scene=scene, active_object=None, region=types.SimpleNamespace(width=260))
    panel_class.draw(types.SimpleNamespace(layout=RecordingLayout(log)), context)
    return log


def test_world_panel_reads_auto_threshold_and_display_panel_has_no_view_warning(bpy_module, empty_scene):
    """An automatic threshold reads "Threshold: Auto" (no 0.00 field); turned off, the number shows.
    The Display panel no longer warns about the view transform: the overlay applies it."""
    from prt_addon.blender.ui import panels

    settings = empty_scene.prt_world
    settings.split_lights = True
    log = draw_panel(panels.VIEW3D_PT_prt_world, empty_scene)
    assert ("prop", "auto_threshold", "Threshold: Auto") in log
    assert not any(entry[:2] == ("prop", "light_threshold") for entry in log)
    settings.auto_threshold = False
    log = draw_panel(panels.VIEW3D_PT_prt_world, empty_scene)
    assert ("prop", "light_threshold", None) in log
    empty_scene.view_settings.view_transform = "AgX"
    log = draw_panel(panels.VIEW3D_PT_prt_display, empty_scene)
    assert log, "the Display panel drew nothing"
    assert not any("view transform" in str(entry).lower() or "Standard" in str(entry) for entry in log), log


def test_the_root_panel_offers_project_world_until_there_is_world_lighting(bpy_module, empty_scene):
    """World Lighting is closed by default (it pushed the Display panel below the fold): until the
    world is projected its button is in the root panel, then the lighting's turn."""
    import types

    from helpers.display_scenes import add_env_world

    from prt_addon.blender.ui import panels

    def root_panel():
        log = []
        context = types.SimpleNamespace(scene=empty_scene, space_data=None, region=types.SimpleNamespace(width=260))
        panels.VIEW3D_PT_prt.draw(types.SimpleNamespace(layout=RecordingLayout(log)), context)
        return log

    assert "DEFAULT_CLOSED" in panels.VIEW3D_PT_prt_world.bl_options
    assert "DEFAULT_CLOSED" not in getattr(panels.VIEW3D_PT_prt_display, "bl_options", set())
    add_env_world(bpy_module, empty_scene)
    assert ("operator", "prt.project_world", None) in root_panel()
    empty_scene.prt_world.stored_order = 4
    log = root_panel()
    assert ("operator", "prt.set_light_rotation", "Add Lighting Rotation") in log
    assert not any(entry[:2] == ("operator", "prt.project_world") for entry in log)
