"""Windows against SH ringing, with an automatic, verified parameter search (a study kept beside
the add-on: docs/windows.md). weights.py holds the windows, search.py the search."""

from .search import AutoWindowResult, auto_window
from .weights import AUTO_KINDS, DEFAULT_TOL, KINDS, apply_window, sphere_grid, window_weights

__all__ = [
    "AUTO_KINDS",
    "AutoWindowResult",
    "DEFAULT_TOL",
    "KINDS",
    "apply_window",
    "auto_window",
    "sphere_grid",
    "window_weights",
]
