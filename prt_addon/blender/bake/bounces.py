"""An interreflected bake's share of the job: the nodes light bounces off, their hits and passes.

Every visible mesh instance is a part of the scene's occluder; its bake points (the same rule as
a bake's points: vertices, or corners where normals split) are the nodes its triangles' hits are
gathered at (core.transfer.bounce). A part that is baked reuses its plan's points and computation; any
other part gets a computation of its own, traced once with the same directions, whose transfer
only feeds the bounces. A texel-baked part's nodes are its covered texels instead: a hit on it
reads the texel under the hit's UV point (core.transfer.texel_hits). After the direct pass the
bounce passes run on the whole node set.
"""

import numpy as np

from ...core.trace import raytrace
from ...core.transfer import bounce, bounce_hits, hit_albedo, texel_hits
from ...core.transfer.mesh import concatenate_parts
from ..scene import mesh_read
from ..scene.parts import ray_setup
from .bounce_albedo import triangle_albedo, triangle_images


def _node_triangles(points, corners, corner_verts):
    """The point of each triangle corner: vertex i for the POINT domain, else the corner's point."""
    return corner_verts[corners] if points.scatter is None else points.scatter[corners]


class BounceSystem:
    """Nodes, hit sink and extra computations of one interreflected bake (job: its BakeJob, whose
    plans have their points; parts and sources: scene_parts' output)."""

    def __init__(self, job, parts, sources):
        s = job.settings
        self.bounces = s.bounces
        self.order = s.order
        self.pool = job._pool
        self.notes = []
        seen, means = set(), {}  # notes said once; image means computed once per image
        plan_of = {plan.obj: plan for plan in job.plans}
        self.plan_offset = {}  # id(plan) -> its first node
        self.node_computations = []  # (first node, computation) of parts that are not baked
        node_triangles, albedo, orientation, extra_parts, textured = [], [], [], [], []
        remap = texel_hits.TexelRemap()
        offset = first_triangle = 0
        for index, ((owner, world, triangles), src) in enumerate(zip(parts, sources)):
            plan = plan_of.get(owner) if owner is not None else None
            if plan is not None and id(plan) in self.plan_offset:
                plan = None
            corners, faces = mesh_read.read_triangle_corners(src.mesh, src.positions)
            if src.kept is not None:
                corners, faces = corners[src.kept], faces[src.kept]
            mirrored = np.linalg.det(src.matrix[:3, :3]) < 0
            if plan is not None and plan.texels is not None:
                count = self._texel_nodes(remap, plan.texels, src.kept, mirrored, first_triangle, offset)
                node_triangles.append(np.full((len(faces), 3), -1, np.int64))  # (the remap's)
            else:
                points = plan.points if plan is not None else mesh_read.bake_points(src.mesh, src.matrix, src.positions)
                local = _node_triangles(points, corners, mesh_read.read_corner_verts(src.mesh))
                node_triangles.append(local.astype(np.int64) + offset)
                count = len(points.positions)
            albedo.append(triangle_albedo(src.obj, src.mesh, faces, self.notes, seen, means, corners))
            for here, uvs, image, sampling, key in triangle_images(src.obj, src.mesh, faces, corners, means):
                textured.append((first_triangle + here, uvs, image, sampling, key))  # (their albedo per hit)
            # A mirrored part (negative determinant) has its winding, hence its geometric
            # normals, reversed in world space: flip them back so its front faces stay front.
            orientation.append(np.full(len(faces), -1.0 if mirrored else 1.0))
            if plan is not None:
                self.plan_offset[id(plan)] = offset
            else:
                extra_parts.append((index, offset, points, world, triangles, src))
            offset += count
            first_triangle += len(triangles)
        self.n_nodes = offset
        albedo = np.concatenate(albedo) if albedo else np.zeros((0, 3))
        grey = bool(np.all(albedo == albedo[:, :1]))
        images = {key: image for _i, _u, image, _s, key in textured}  # (each image once, not per instance)
        grey = grey and all(np.all(image == image[..., :1]) for image in images.values())
        self.channels = 1 if grey else 3
        vertices, triangles = concatenate_parts(parts)
        self.sink = bounce_hits.HitTransport(
            vertices,
            triangles,
            np.concatenate(node_triangles) if node_triangles else np.zeros((0, 3), np.int64),
            albedo[:, :1] if grey else albedo,
            len(job.directions.directions),
            seed=s.seed,
            orientation=np.concatenate(orientation) if orientation else None,
        )
        if remap.parts:
            self.sink.remap = remap
        if textured:
            lookup = hit_albedo.HitAlbedo(len(triangles))
            for index, uvs, image, sampling, key in textured:
                lookup.add(index, uvs, image, key, sampling)
            self.sink.set_hit_albedo(lookup)
        boxes = [raytrace.bounding_box(v) for _o, v, _t in parts]
        for index, first, points, world, tris, src in extra_parts:
            self.node_computations.append((first, self._computation(job, points, world, tris, src, boxes, index)))
        self.extra_points = sum(len(c.positions) for _f, c in self.node_computations)
        self.passes = None
        self.bounced = {}  # id(plan) -> (P, C, nn) bounced transfer

    @staticmethod
    def _texel_nodes(remap, geometry, kept, mirrored, first_triangle, first_node):
        """Add a texel-baked part's texels to `remap` (its triangles: the loop triangles of
        geometry.uvs, those `kept`); returns its node count."""
        uvs = geometry.uvs if kept is None else geometry.uvs[kept]
        if mirrored:  # (the sink stores a mirrored triangle as (a, c, b): its barycentrics follow)
            uvs = uvs[:, [0, 2, 1]]
        samples = geometry.samples
        remap.add(first_triangle, first_node, texel_hits.TexelNodes(uvs, samples.texels, samples.resolution))
        return samples.count

    def _computation(self, job, points, world, triangles, src, boxes, index):
        s = job.settings
        offset, self_occludes = ray_setup(world, triangles, src.mesh, s.cull)
        others = None
        if s.cull:
            others = np.array([b for k, b in enumerate(boxes) if k != index]).reshape(-1, 2, 3)
        surface = (world, triangles)
        return job.transfer_computation(points, job._occluder, offset, self_occludes, others, surface, self.sink)

    def start_passes(self, plans):
        """Build the transport from every computation's hits (which are then freed) and queue the
        passes; step_pass() runs them."""
        nn = self.order * self.order
        direct = np.zeros((self.n_nodes, nn), dtype=np.float32)
        entries = []
        node_sources = [(self.plan_offset[id(p)], p.computation) for p in plans if id(p) in self.plan_offset]
        # In node order, so that the rows arrive sorted (no argsort of every entry).
        for first, comp in sorted(node_sources + self.node_computations, key=lambda fc: fc[0]):
            direct[first : first + comp.total] = comp.coeffs
            for rows, _nodes, _w in comp.hits:
                rows += np.int32(first)  # (in place: the sink's arrays, no copy)
            entries += comp.hits
            comp.hits = []
        matrix = bounce.Transport(entries, self.n_nodes, self.channels)
        del entries
        self._receivers = [p for p in plans if id(p) not in self.plan_offset]  # not in the scene
        extra = [bounce.Transport(p.computation.hits, p.computation.total, self.channels) for p in self._receivers]
        self.transport_bytes = matrix.nbytes + sum(r.nbytes for r in extra)
        self.passes = bounce.BouncePasses(direct, matrix, self.bounces, extra, self.pool)
        self._plans = plans

    def step_pass(self):
        """One bounce pass; False when all are done (the results are then in `bounced`)."""
        more = self.passes.step()
        if not more:
            total = self.passes.total
            for plan in self._plans:
                if id(plan) in self.plan_offset:
                    first = self.plan_offset[id(plan)]
                    self.bounced[id(plan)] = total[first : first + plan.computation.total]
            for plan, values in zip(self._receivers, self.passes.extra_out):
                self.bounced[id(plan)] = values
            if self.channels == 3:  # grey rows broadcast to the colour channels
                for key, values in self.bounced.items():
                    self.bounced[key] = np.broadcast_to(values, (len(values), 3, values.shape[2]))
        return more

    def close(self):
        for _first, comp in self.node_computations:
            comp.close()
