"""The specular's GLSL on the GPU against numpy: the sky levels' trilinear fetch, the split-sum table's bilinear one, the caps' intersection."""

import numpy as np

SIZE = (48, 32)  # the target: one looked-up direction (or table point) per pixel


def _lookup_shader():
    import gpu

    from prt_addon.blender.display import shader_specular

    info = gpu.types.GPUShaderCreateInfo()
    info.typedef_source(shader_specular.UBO_SOURCE)
    info.uniform_buf(2, "PRTSpec", "spec")
    info.sampler(0, "FLOAT_2D", "query_tx")
    info.sampler(shader_specular.SKY_SLOT, "FLOAT_3D", "sky_tx")
    info.sampler(shader_specular.BRDF_SLOT, "FLOAT_2D", "brdf_tx")
    info.push_constant("INT", "mode")
    info.vertex_in(0, "VEC2", "pos")
    info.fragment_out(0, "VEC4", "FragColor")
    info.vertex_source("void main()\n{\n  gl_Position = vec4(pos, 0.0, 1.0);\n}\n")
    info.fragment_source(
        shader_specular.LOOKUP_GLSL
        + shader_specular.CAP_GLSL
        + "void main()\n{\n  vec4 q = texelFetch(query_tx, ivec2(gl_FragCoord.xy), 0);\n"
        "  FragColor = mode == 0 ? vec4(sky_radiance(q.xyz, q.w), 1.0) : vec4(brdf_ab(q.x, q.y), 0.0, 1.0);\n"
        "  FragColor = mode == 2 ? vec4(cap_intersection(q.x, q.y, q.z), 0.0, 0.0, 1.0) : FragColor;\n}\n"
    )
    return gpu.shader.create_from_info(info)


def _draw(query, mode, sky, rows, table):
    """(H, W, 4) of the shader run on each pixel's query (xyz w: direction and roughness; or n.v,
    roughness; or the caps' three cosines)."""
    import gpu
    from gpu_extras.batch import batch_for_shader

    from prt_addon.blender.display import shader_specular

    w, h = SIZE
    data = np.ascontiguousarray(query, dtype=np.float32).reshape(-1)
    query_tx = gpu.types.GPUTexture((w, h), format="RGBA32F", data=gpu.types.Buffer("FLOAT", data.size, data))
    ubo = gpu.types.GPUUniformBuf(
        shader_specular.spec_ubo_bytes(np.eye(4), np.eye(3), (0.0, 0.0, 1.0, 0.0), rows, sky, (0.5, 0.0, 0.04, 1.0))
    )
    shader = _lookup_shader()
    batch = batch_for_shader(shader, "TRIS", {"pos": [(-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0)]})
    off = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    with off.bind():
        shader.bind()
        shader.uniform_block("spec", ubo)
        shader.uniform_sampler("query_tx", query_tx)
        shader.uniform_sampler("sky_tx", sky.texture)
        shader.uniform_sampler("brdf_tx", table)
        shader.uniform_int("mode", mode)
        batch.draw(shader)
        out = np.array(gpu.state.active_framebuffer_get().read_color(0, 0, w, h, 4, 0, "FLOAT").to_list())
    off.free()
    return out.reshape(h, w, 4)


def _numpy_sky(levels, rows, d, roughness):
    """The equirect levels looked up as the shader used to, texel by texel: bilinear with the
    longitude wrapped and the latitude clamped, linear between the two nearest levels."""
    count, h, w = levels.shape[:3]
    q = d @ rows.T
    u = -np.arctan2(q[:, 1], q[:, 0]) / (2 * np.pi) + 0.5
    v = np.arctan2(q[:, 2], np.hypot(q[:, 0], q[:, 1])) / np.pi + 0.5
    px, py = u * w - 0.5, np.clip(v * h - 0.5, 0.0, h - 1)
    x0, y0 = np.floor(px).astype(int), np.floor(py).astype(int)
    fx, fy = (px - x0)[:, None], (py - y0)[:, None]
    x0, x1 = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    level = roughness * (count - 1)
    l0 = np.floor(level).astype(int)
    l1 = np.minimum(l0 + 1, count - 1)

    def bilinear(k):
        a = levels[k, y0, x0] * (1 - fx) + levels[k, y0, x1] * fx
        b = levels[k, y1, x0] * (1 - fx) + levels[k, y1, x1] * fx
        return a * (1 - fy) + b * fy

    fl = (level - l0)[:, None]
    return bilinear(l0) * (1 - fl) + bilinear(l1) * fl


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_sky_fetch_matches_the_levels_bilinear(gpu_ready):
    """Random levels (every texel independent, so any misplaced texel or weight shows), turned by
    random rows, looked up at random directions (some on the longitude seam) and roughness: the
    one trilinear fetch gives the texel-by-texel lookup within the half-float storage and the
    filter's weight precision; a nearest-texel lookup would be far off."""
    from prt_addon.blender.display import sky_texture

    rng = np.random.default_rng(7)
    levels = rng.uniform(0.0, 1.0, size=(7, 8, 16, 3))
    sky = sky_texture.levels_texture(levels)
    rows = _random_rotation(rng)
    n = SIZE[0] * SIZE[1]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    seam = rng.uniform(-1.0, 1.0, size=n // 4) * np.pi / 16 / 2  # within half a texel of u = 0 (-X)
    lat = rng.uniform(-1.2, 1.2, size=n // 4)
    image_dir = np.stack([-np.cos(lat) * np.cos(seam), np.cos(lat) * np.sin(seam), np.sin(lat)], axis=1)
    d[: n // 4] = image_dir @ rows  # (rows @ d is the image direction)
    roughness = rng.uniform(0.0, 1.0, size=n)
    roughness[:8] = (0.0, 1.0, 1 / 6, 0.5, 0.999, 0.001, 5 / 6, 2 / 6)
    query = np.concatenate([d, roughness[:, None]], axis=1)
    got = _draw(query, 0, sky, rows, sky_texture.brdf_texture())[..., :3].reshape(n, 3)
    expected = _numpy_sky(levels, rows, d, roughness)
    error = np.abs(got - expected)
    assert error.max() < 0.01, error.max()  # (2e-4 measured here; 8-bit filter weights allow 4e-3)
    assert error[: n // 4].max() < 0.01  # the seam
    nearest = levels[np.rint(roughness * 6).astype(int), 0, 0]  # (a lookup ignoring the position)
    assert np.abs(nearest - expected).mean() > 0.1


def test_table_fetch_matches_the_tables_bilinear(gpu_ready):
    """The split-sum table looked up by one filtered fetch gives its bilinear interpolation,
    clamped at the edges (n.v near 0 and 1, roughness 0 and 1)."""
    from prt_addon.blender.display import sky_texture
    from prt_addon.core.specular import brdf

    table = brdf.brdf_table()
    size = table.shape[0]
    rng = np.random.default_rng(3)
    n = SIZE[0] * SIZE[1]
    points = rng.uniform(0.0, 1.0, size=(n, 2))
    points[:4] = ((0.0, 0.0), (1.0, 1.0), (1e-4, 0.5), (0.999, 0.01))
    query = np.concatenate([points, np.zeros((n, 2))], axis=1)
    sky = sky_texture.levels_texture(np.zeros((2, 2, 4, 3)))
    got = _draw(query, 1, sky, np.eye(3), sky_texture.brdf_texture())[..., :2].reshape(n, 2)
    p = np.clip(points * size - 0.5, 0.0, size - 1)
    a = np.floor(p).astype(int)
    b = np.minimum(a + 1, size - 1)
    f = p - a
    # (the table's rows are roughness, its columns n.v)
    low = table[a[:, 1], a[:, 0]] * (1 - f[:, :1]) + table[a[:, 1], b[:, 0]] * f[:, :1]
    high = table[b[:, 1], a[:, 0]] * (1 - f[:, :1]) + table[b[:, 1], b[:, 0]] * f[:, :1]
    expected = low * (1 - f[:, 1:]) + high * f[:, 1:]
    assert np.abs(got - expected).max() < 2e-3, np.abs(got - expected).max()


def test_cap_intersection_matches_the_core(gpu_ready):
    """The GLSL caps' intersection (its containment tests on cosines) gives core.specular.occlusion's
    (on angles) for random caps and axes, nested, apart, overlapping and at the hemisphere (cos 0)."""
    from prt_addon.blender.display import sky_texture
    from prt_addon.core.specular import occlusion

    rng = np.random.default_rng(11)
    n = SIZE[0] * SIZE[1]
    cosines = rng.uniform(-1.0, 1.0, size=(n, 3))
    cosines[: n // 4, 0] = 0.0  # the open hemisphere, as the shader's first call
    cosines[n // 4 : n // 2, 1] = rng.uniform(0.99, 1.0, size=n // 4)  # glossy lobes
    query = np.concatenate([cosines, np.zeros((n, 1))], axis=1)
    sky = sky_texture.levels_texture(np.zeros((2, 2, 4, 3)))
    got = _draw(query, 2, sky, np.eye(3), sky_texture.brdf_texture())[..., 0].reshape(n)
    expected = occlusion.cap_intersection(cosines[:, 0], cosines[:, 1], cosines[:, 2])
    smaller = 2 * np.pi * (1 - np.maximum(cosines[:, 0], cosines[:, 1]))
    assert ((expected > 0) & (expected < smaller)).mean() > 0.2  # (many partial overlaps)
    assert np.abs(got - expected).max() < 5e-3, np.abs(got - expected).max()  # (6e-4 measured: float32 acos)
