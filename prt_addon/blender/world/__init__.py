"""The World: its node tree, its pixels, and its projection into SH lighting."""
