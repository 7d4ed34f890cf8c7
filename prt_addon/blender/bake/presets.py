"""Bake presets: the order, sample count and bounces for a quick look, a good default and a final bake.

Chosen from the accuracy report (docs/accuracy.md): 256 to 512 Fibonacci directions come within
a fraction of a point of the band limit, so the order sets the error; with the light split, the
sky left in SH is smooth and order 4 reaches a few percent. Every preset bakes Cycles' default
count of diffuse bounces (Light Paths > Max Bounces > Diffuse, 4): without them a room's walls
and ceiling are far darker than Cycles shows them (docs/bake.md, "Defaults").
"""

CYCLES_DIFFUSE_BOUNCES = 4  # Cycles' default of scene.cycles.diffuse_bounces

PRESETS = {
    "DRAFT": ("Draft", "Order 2, 64 directions, 4 bounces: a quick look at soft shadows", 2, 64, 4),
    "GOOD": (
        "Good",
        "Order 4, 256 directions, 4 bounces (as Cycles): the default, a few percent from Cycles with the light split",
        4,
        256,
        4,
    ),
    "FINAL": (
        "Final",
        "Order 8, 512 directions, 4 bounces: the finest soft shadows, slower to bake and draw",
        8,
        512,
        4,
    ),
}


def preset_of(order, samples, bounces):
    """The key of the preset with this order, sample count and bounces, or 'CUSTOM'."""
    for key, (_label, _tip, preset_order, preset_samples, preset_bounces) in PRESETS.items():
        if (order, samples, bounces) == (preset_order, preset_samples, preset_bounces):
            return key
    return "CUSTOM"
