"""The occluder protocol every ray-tracing backend implements, and the lazily built occluder of a bake.

The backends are injected (`builders`: name -> class taking (vertices, triangles)), so this
module needs no Blender: the Blender layer passes its BVH-tree occluder beside Embree's.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from concurrent.futures import Executor, Future
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt


class Occluder(Protocol):
    """What the core traces against: core.trace.raytrace.EmbreeOccluder, the Blender layer's
    BVH-tree occluder and LazyOccluder all implement it."""

    name: str  # the backend's name ("EMBREE", "BVHTREE")
    max_threads: int  # how many Python threads may call occluded() at once usefully

    def occluded(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
        """(N,) bool: whether each ray (origin, unit direction; float32 (N, 3)) hits a triangle."""
        ...

    def nearest_triangles(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
        """(N,) int: the index of the nearest triangle each ray hits, -1 where it hits none."""
        ...


class LazyOccluder:
    """The real occluder, built on the first query or in the background after start() (the
    scene's Embree occluder: its build overlaps the job's set-up); queries wait for the build."""

    def __init__(
        self,
        backend: str,
        vertices: npt.ArrayLike,
        triangles: npt.ArrayLike,
        builders: Mapping[str, Callable[[Any, Any], Occluder]],
    ) -> None:
        self.name = backend
        self._builder = builders[backend]
        self.max_threads = int(getattr(self._builder, "max_threads", 1))
        self._parts: Any = (vertices, triangles)  # None once built
        self._real: Occluder | None = None
        self._lock = threading.Lock()
        self._started: Future[None] | None = None

    def start(self, pool: Executor) -> None:
        """Build in the background on `pool` (Embree only: the BVH build releases the GIL, and
        attaching the triangles as shared buffers takes microseconds where embreex's copying
        constructor would hold the GIL for its whole copy) while the caller prepares the rest.
        A failure there is not raised: the first query builds again and raises it, as without
        start()."""
        if self.name == "EMBREE" and self._started is None:
            self._started = pool.submit(self._build_quietly)

    def _build_quietly(self):
        try:
            self._build()
        except Exception:
            pass

    @property
    def built(self) -> bool:
        return self._real is not None

    def _build(self) -> Occluder:
        with self._lock:
            if self._real is None:
                vertices, triangles = self._parts
                self._real = self._builder(vertices, triangles)
                self._parts = None
        return self._real

    def occluded(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
        real = self._real if self._real is not None else self._build()
        return real.occluded(origins, directions)

    def nearest_triangles(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
        real = self._real if self._real is not None else self._build()
        return real.nearest_triangles(origins, directions)
