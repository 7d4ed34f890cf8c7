"""Bake presets: the order and sample count for a quick look, a good default and a final bake.

Chosen from the accuracy report (docs/accuracy.md): 256 to 512 Fibonacci directions come within
a fraction of a point of the band limit, so the order sets the error; with the light split, the
sky left in SH is smooth and order 4 reaches a few percent.
"""

PRESETS = {
    "DRAFT": ("Draft", "Order 2, 64 directions: a quick look at soft shadows", 2, 64),
    "GOOD": ("Good", "Order 4, 256 directions: the default, a few percent from Cycles with the light split", 4, 256),
    "FINAL": ("Final", "Order 8, 512 directions: the finest soft shadows, slower to bake and draw", 8, 512),
}


def preset_of(order, samples):
    """The key of the preset with this order and sample count, or 'CUSTOM'."""
    for key, (_label, _tip, preset_order, preset_samples) in PRESETS.items():
        if (order, samples) == (preset_order, preset_samples):
            return key
    return "CUSTOM"
