"""The add-on registers, unregisters and registers again in one process; the core needs no bpy."""


def test_register_unregister_register(bpy_module):
    import prt_addon

    prt_addon.register()
    assert hasattr(bpy_module.types.Scene, "prt")
    assert hasattr(bpy_module.types, "VIEW3D_PT_prt")
    prt_addon.register()  # a second register() without unregister() must not fail
    prt_addon.unregister()
    assert not hasattr(bpy_module.types.Scene, "prt")
    assert not hasattr(bpy_module.types, "VIEW3D_PT_prt")
    prt_addon.unregister()  # unregistering twice is harmless
    prt_addon.register()
    assert hasattr(bpy_module.types.Scene, "prt")
    # Left registered: the session-wide `addon` fixture unregisters at the end.


def test_every_setting_has_a_tooltip(bpy_module, addon):
    """Every property of every PRT PropertyGroup says what it is (the tooltip Blender shows)."""
    from prt_addon.blender.ui import properties

    groups = [getattr(properties, n) for n in dir(properties) if n.startswith("PRT_PG_")]
    assert groups
    missing = [
        f"{group.__name__}.{prop.identifier}"
        for group in groups
        for prop in group.bl_rna.properties
        if prop.identifier not in ("rna_type", "name") and not prop.description
    ]
    assert not missing, missing
