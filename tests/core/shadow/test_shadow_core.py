"""Shadow methods in numpy against closed forms (no bpy): planar projection, volumes, maps, metrics."""
import math

import numpy as np
import pytest

from addon.core import camera, geometry
from addon.core.shadow import metrics as shadow_metrics
from addon.core.shadow import volume as shadow_volume
from addon.core.shadow import depth_map
from addon.core.shadow import planar as shadow_planar
from addon.core.shadow import raster
from addon.core.errors import InputError

from tests.core.ssao.test_ssao_synthetic import look_at, perspective


def _look_down(eye, width=48, height=48, fov=math.radians(60), ortho=None):
    """A camera at ``eye`` looking straight down -Z (world_to_view, proj) with Blender's conventions."""
    w2v = np.eye(4)
    w2v[:3, 3] = -np.asarray(eye, float)            # view axes = world axes: looking down -Z
    n, f = 0.01, 100.0
    if ortho:
        proj = np.diag([2 / ortho, 2 / ortho, -2 / (f - n), 1.0])
        proj[2, 3] = -(f + n) / (f - n)
    else:
        t = 1 / math.tan(fov / 2)
        proj = np.array([[t, 0, 0, 0], [0, t, 0, 0], [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]])
    return w2v, proj, width, height


def _cube(lo, hi):
    """Closed, outward-wound box (8 vertices, 12 triangles)."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, t


def _floor_rays(w2v, proj, w, h):
    """Camera rays, their hits on the floor z = 0 and the distances to them."""
    o, d = camera.pixel_rays(w2v, proj, w, h)
    t = -o[..., 2] / d[..., 2]
    return o, d, o + t[..., None] * d


def test_planar_projection_lands_on_the_plane_along_the_light_ray():
    plane = shadow_planar.plane_from_point_normal((0, 0, 0.5), (0, 0, 2))
    light = np.array([1.0, 2.0, 5.0, 1.0])
    s = shadow_planar.projection_matrix(plane, light)
    p = np.array([[0.3, -0.2, 1.5], [-1.0, 0.4, 2.0]])
    q = shadow_planar.project(p, s)
    np.testing.assert_allclose(q[:, 2], 0.5, atol=1e-12)
    # closed form: q = L + (p - L) * (L_z - 0.5) / (L_z - p_z)
    expect = light[:3] + (p - light[:3]) * ((light[2] - 0.5) / (light[2] - p[:, 2]))[:, None]
    np.testing.assert_allclose(q, expect, atol=1e-12)
    sun = np.array([0.0, 0.6, 0.8, 0.0])                      # toward the light, w = 0
    q = shadow_planar.project(p, shadow_planar.projection_matrix(plane, sun))
    np.testing.assert_allclose(q, p - (p[:, 2:] - 0.5) / 0.8 * sun[:3], atol=1e-12)


def test_planar_mask_covers_the_projected_square_only():
    w2v, proj, w, h = _look_down((0, 0, 6), 64, 64)
    o, d, hit = _floor_rays(w2v, proj, w, h)
    depth = np.full((h, w), 6.0)                               # planar view depth of the floor
    v, t = _cube((-0.5, -0.5, 1.0), (0.5, 0.5, 1.2))
    cover = shadow_planar.planar_shadow_mask(v[t], shadow_planar.plane_from_point_normal((0, 0, 0), (0, 0, 1)),
                                             np.array([0, 0, 1.0, 0]), w2v, proj, w, h, depth)
    inside = (np.abs(hit[..., 0]) < 0.5) & (np.abs(hit[..., 1]) < 0.5)
    edge = (np.abs(np.abs(hit[..., 0]) - 0.5) < 0.06) | (np.abs(np.abs(hit[..., 1]) - 0.5) < 0.06)
    assert np.array_equal(cover[~edge], inside[~edge]) and inside.sum() > 50
    hidden = shadow_planar.planar_shadow_mask(v[t], shadow_planar.plane_from_point_normal((0, 0, 0), (0, 0, 1)),
                                              np.array([0, 0, 1.0, 0]), w2v, proj, w, h, depth - 0.5)
    assert not hidden.any()                                    # a raised receiver hides the shadow (stairs)


def _area(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def test_clipping_keeps_exactly_the_part_in_front_of_a_plane_with_its_winding():
    tri = np.array([[[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]]])       # area 8, normal +z
    # keep P.[x, 1] >= 0 for P = (0, s, 0, d): the part of the triangle with s*y >= -d;
    # the width of the triangle at height y is 4 - y, so the kept areas are integrals of it
    cases = [((0, -1, 0, 1), 3.5),     # y <= 1: two vertices in, a quad (two triangles)
             ((0, 1, 0, -3), 0.5),     # y >= 3: one vertex in, a smaller triangle
             ((0, 1, 0, 1), 8.0),      # all in
             ((0, 1, 0, -5), 0.0)]     # all out
    for plane, area in cases:
        for swap in (False, True):     # the same cut along x (other vertex order)
            p = np.array(plane, float)
            if swap:
                p[[0, 1]] = p[[1, 0]]
            kept = raster.clip_triangles(tri, p)
            rest = raster.clip_triangles(tri, -p)
            assert abs(_area(kept).sum() - area) < 1e-12 and abs(_area(rest).sum() - (8 - area)) < 1e-12
            assert np.all(kept @ p[:3] + p[3] >= -1e-12)
            normals = np.cross(kept[:, 1] - kept[:, 0], kept[:, 2] - kept[:, 0])
            assert np.all(normals[:, 2] >= 0) and np.allclose(normals[:, :2], 0)   # winding kept


def test_planar_shadow_of_a_box_standing_on_the_plane_and_reaching_behind_the_camera():
    """A box standing on the floor under a tilted sun: its shadow is the base swept along the light
    (vertices on the plane stay). The camera stands in the shadow of a wide slab, so shadow
    triangles cross its near plane and must be clipped, not dropped."""
    w2v = look_at((0.3, -0.4, 1.0), (0.3, 3.0, 0.0))
    proj = perspective(lens=20.0)
    w, h = 48, 48
    o, d = camera.pixel_rays(w2v, proj, w, h)
    t = -o[..., 2] / d[..., 2]
    hit = o + t[..., None] * d
    floor = t > 0
    c2w = np.linalg.inv(w2v)
    depth = np.where(floor, (hit - c2w[:3, 3]) @ -c2w[:3, 2], 1e9)    # planar view depth of the floor
    to_sun = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    plane = shadow_planar.plane_from_point_normal((0, 0, 0), (0, 0, 1))
    sun = np.append(to_sun, 0.0)
    v, tt = _cube((-0.4, 1.5, 0.0), (0.4, 2.3, 0.8))               # stands on the floor
    slab_v, slab_t = _cube((-20, -20, 3.0), (20, 1.2, 3.2))          # shades the floor around the camera
    tris = np.concatenate([v[tt], slab_v[slab_t]])
    cover = shadow_planar.planar_shadow_mask(tris, plane, sun, w2v, proj, w, h, depth)
    # analytic: floor point p is shadowed iff p + s to_sun meets the box (0 <= s to_sun_z <= 0.8)
    # or the slab
    s = np.linspace(0.0, 0.8 / to_sun[2], 401)
    ray = hit[..., None, :2] + s[:, None] * to_sun[:2]
    in_box = ((np.abs(ray[..., 0]) <= 0.4) & (ray[..., 1] >= 1.5) & (ray[..., 1] <= 2.3)).any(-1)
    at_slab = hit[..., :2] + (3.1 / to_sun[2]) * to_sun[:2]
    in_slab = (np.abs(at_slab[..., 0]) <= 20) & (at_slab[..., 1] >= -20) & (at_slab[..., 1] <= 1.2)
    truth = floor & (in_box | in_slab)
    assert truth[floor].mean() > 0.2 and (~truth[floor]).mean() > 0.2
    wrong = np.mean(cover[floor] != truth[floor])
    assert wrong < 0.03, wrong                                       # only the edge pixels may differ


def test_open_mesh_is_rejected_for_shadow_volumes():
    v, t = _cube((0, 0, 0), (1, 1, 1))
    with pytest.raises(InputError, match="not a closed mesh"):
        shadow_volume.volume_triangles(v, t[:-1], np.array([0, 0, 1.0, 0]), 10.0, name="Lid")
    assert shadow_volume.is_closed(t) and not shadow_volume.is_closed(t[2:])


def test_cube_silhouette_under_overhead_sun_is_its_four_top_edges():
    v, t = _cube((0, 0, 0), (1, 1, 1))
    nb = shadow_volume.edge_neighbours(t)
    facing = shadow_volume.light_facing(v, t, np.array([0, 0, 1.0, 0]))
    sil = shadow_volume.silhouette(t, nb, facing)
    assert len(sil) == 4 and np.allclose(v[sil][..., 2], 1.0)


@pytest.mark.parametrize("eye, zpass_ok", [((0.2, 0.1, 6.0), True), ((0.1, 0.05, 0.5), False)])
def test_stencil_counts_match_the_analytic_shadow(eye, zpass_ok):
    """Box at z in [1, 2] under a sun tilted in x: the floor shadow is the box's top square sheared."""
    w2v, proj, w, h = _look_down(eye, 40, 40, fov=math.radians(100) if eye[2] < 1 else math.radians(60))
    o, d, hit = _floor_rays(w2v, proj, w, h)
    tau = shadow_volume.surface_distance(hit, o, d)
    v, t = _cube((-0.6, -0.6, 1.0), (0.6, 0.6, 2.0))
    to_sun = np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0])
    vol, nsil = shadow_volume.volume_triangles(v, t, np.append(to_sun, 0.0), 100.0)
    assert nsil == 6
    # analytic: floor point p is shadowed iff p + s * to_sun hits the box for some s
    s_lo, s_hi = 1.0 / to_sun[2], 2.0 / to_sun[2]
    xs = hit[..., 0][..., None] + np.linspace(s_lo, s_hi, 201) * to_sun[0]
    truth = (np.abs(hit[..., 1]) < 0.6) & (np.abs(xs) < 0.6).any(-1)
    for mode in ("zpass", "zfail"):
        shadow = shadow_volume.stencil(vol, o, d, tau, w2v, proj, w, h, near=0.01, mode=mode) != 0
        wrong = np.mean(shadow != truth)
        if mode == "zfail" or zpass_ok:
            assert wrong < 0.01, (mode, wrong)
        else:
            assert wrong > 0.3, (mode, wrong)                  # the camera sits inside the volume


def _plane_map(size, tilt):
    """Orthographic depth map (looking down from z = 10) of the plane z = tilt * x."""
    w2v, proj, _, _ = _look_down((0, 0, 10), ortho=4.0)
    o, d = camera.pixel_rays(w2v, proj, size, size)
    x = o[..., 0]
    return depth_map.DepthMap(10 - tilt * x, w2v, proj)


def test_shadow_map_acne_needs_slope_bias_and_constant_bias_cures_it():
    tilt = 1.0
    m = _plane_map(64, tilt)
    rng = np.random.default_rng(3)
    p = np.column_stack([rng.uniform(-1.5, 1.5, 4000), rng.uniform(-1.5, 1.5, 4000), np.zeros(4000)])
    p[:, 2] = tilt * p[:, 0]
    n = np.tile(np.array([-tilt, 0, 1]) / math.hypot(tilt, 1), (len(p), 1))
    up = np.tile([0.0, 0.0, 1.0], (len(p), 1))
    no_bias = depth_map.lit_fraction([m], p, n, up, 0.0, 0.0, 1)
    # half the points sit below their texel centre's depth: acne on about 50 %
    assert 0.35 < np.mean(no_bias < 0.5) < 0.65
    # half a texel (4/64 m) times tan 45° is the worst depth error: slope bias 0.5 texel cures it
    assert np.all(depth_map.lit_fraction([m], p, n, up, 0.0, 0.51, 1) == 1.0)
    assert np.all(depth_map.lit_fraction([m], p, n, up, 0.5 * 4 / 64 * tilt + 1e-9, 0.0, 3) >= 0.5)


def test_pcf_kernel_must_be_odd_and_positive():
    for k in (0, 2, -1, 1.5):
        with pytest.raises(InputError):
            depth_map.check_pcf(k)
    assert depth_map.check_pcf(5) == 5


def test_pcf_averages_the_neighbourhood():
    depth = np.full((9, 9), 5.0)
    depth[:, :4] = 1.0                                        # occluder over the left columns
    x = np.array([4.0, 3.0, 6.0])
    frac = depth_map.pcf_lookup(depth, x, np.full(3, 4.0), np.full(3, 4.0), 0.0, 3)
    np.testing.assert_allclose(frac, [2 / 3, 1 / 3, 1.0])


def test_confusion_splits_false_shadow_and_false_light():
    ref = np.array([[1, 1, 0, 0]], bool)
    mask = np.array([[1, 0, 1, 0]], bool)
    rec = np.array([[1, 1, 1, 1]], bool)
    c = shadow_metrics.confusion(mask, ref, rec)
    assert c == {"error": 0.5, "false_shadow": 0.25, "false_light": 0.25, "receiver_pixels": 4}
    img = shadow_metrics.error_image(mask, ref, rec)
    assert tuple(img[0, 1]) == shadow_metrics.COLOURS["false_shadow"]
    assert tuple(img[0, 2]) == shadow_metrics.COLOURS["false_light"]
    with pytest.raises(InputError, match="pixel grid"):
        shadow_metrics.confusion(mask[:, :3], ref, rec)


def test_reference_threshold_is_half_the_unshadowed_value():
    n = np.array([[0, 0, 1.0]] * 3)
    l = np.array([[0, 0, 1.0]] * 3)
    u = shadow_metrics.unshadowed_diffuse(n, l, 3.0)
    np.testing.assert_allclose(u, 3 / np.pi)
    lit = shadow_metrics.lit_from_pass(np.array([3 / np.pi, 0.0, 0.49 * 3 / np.pi]), u, np.ones(3, bool))
    assert lit.tolist() == [True, False, False]


def _ray_cast_depth(tris, w2v, proj, n, near, far):
    """Planar view depth of the nearest hit in [near, far] along each texel-centre ray (brute force)."""
    o, d = camera.pixel_rays(w2v, proj, n, n)
    t = geometry.ray_triangle(o.reshape(-1, 1, 3), d.reshape(-1, 1, 3), tris[None, :, 0], tris[None, :, 1],
                              tris[None, :, 2])
    hit = o.reshape(-1, 1, 3) + np.nan_to_num(t)[..., None] * d.reshape(-1, 1, 3)
    depth = -(hit @ w2v[:3, :3].T + w2v[:3, 3])[..., 2]
    ok = (t > 0) & (depth >= near) & (depth <= far)
    best = np.where(ok, depth, np.inf).min(1).reshape(n, n)
    return np.where(np.isfinite(best), best, camera.SKY_DEPTH)


def _box_over_floor():
    v, t = _cube((-0.5, -0.4, 0.6), (0.7, 0.5, 1.3))
    floor = np.array([[[-3.1, -2.9, 0.05], [3.2, -3.0, -0.1], [2.9, 3.1, 0.0]],
                      [[-3.1, -2.9, 0.05], [2.9, 3.1, 0.0], [-3.0, 3.05, 0.1]]])
    return np.concatenate([v[t], floor])


@pytest.mark.parametrize("kind", ["ortho", "perspective"])
def test_rasterised_depth_is_the_nearest_hit_along_each_texel_centre_ray(kind):
    """Orthographic depth is affine across a triangle, perspective depth is not (1/d is): both must agree
    with a ray cast through every texel centre, the sky included, and not depend on the chunk size."""
    tris = _box_over_floor()
    n, near, far = 40, 1e-3, 100.0
    if kind == "ortho":
        w2v, proj, _, _ = _look_down((0.1, 0.05, 5.0), ortho=7.0)
    else:
        w2v, proj, _, _ = _look_down((0.1, 0.05, 4.0), fov=math.radians(80))
    ref = _ray_cast_depth(tris, w2v, proj, n, near, far)
    got = raster.rasterize_depth(tris, w2v, proj, n, n, near, far)
    sky = ref == camera.SKY_DEPTH
    assert 0 < sky.sum() < sky.size / 2 and (ref[~sky] < 4.5).any()        # floor, box top and sky all seen
    np.testing.assert_array_equal(got == camera.SKY_DEPTH, sky)
    np.testing.assert_allclose(got[~sky], ref[~sky], rtol=1e-12, atol=1e-12)
    stats = {}
    np.testing.assert_array_equal(raster.rasterize_depth(tris, w2v, proj, n, n, near, far, chunk=7, stats=stats), got)
    assert stats["fragments"] >= (~sky).sum() and stats["triangles"] == len(tris)


def test_rasterised_depth_is_clipped_at_the_near_and_far_planes():
    """Camera rays start on the plane d = near and end on d = far: a box the near plane cuts shows its
    inside (the far wall), a floor beyond far is sky; a quad's shared diagonal leaves no crack."""
    tris = _box_over_floor()
    w2v, proj, _, _ = _look_down((0.1, 0.05, 2.0), fov=math.radians(120))    # box top at d = 0.7, bottom 1.4
    n = 32
    for near, far in ((0.9, 100.0), (1e-3, 1.5)):
        ref = _ray_cast_depth(tris, w2v, proj, n, near, far)
        got = raster.rasterize_depth(tris, w2v, proj, n, n, near, far)
        np.testing.assert_array_equal(got == camera.SKY_DEPTH, ref == camera.SKY_DEPTH)
        np.testing.assert_allclose(got, ref, rtol=1e-12)
        seen = got[got < camera.SKY_DEPTH]
        if near == 0.9:
            assert np.isclose(seen, 1.4).any() and not np.isclose(seen, 0.7).any()   # the top is cut away
        else:
            assert np.isclose(seen, 0.7).any() and seen.max() <= 1.5 and (got == camera.SKY_DEPTH).any()
    # a square exactly filling an orthographic view: every texel centre is inside one of its two triangles
    w2v, proj, _, _ = _look_down((0.0, 0.0, 2.0), ortho=2.0)
    quad = np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1, -1, 0], [1, 1, 0], [-1, 1, 0]]], float)
    np.testing.assert_allclose(raster.rasterize_depth(quad, w2v, proj, 64, 64, 1e-3), 2.0)


def _height_field(n=72, size=6.0):
    """An n x n grid of bumps as 2 n² small triangles (10 368 at n = 72): about one triangle per texel row."""
    x = np.linspace(-size / 2, size / 2, n + 1)
    gx, gy = np.meshgrid(x, x)
    p = np.stack([gx, gy, 0.3 * np.sin(3 * gx) * np.cos(2 * gy)], -1)
    a, b, c, d = p[:-1, :-1], p[:-1, 1:], p[1:, :-1], p[1:, 1:]
    return np.concatenate([np.stack([a, b, d], -2).reshape(-1, 3, 3), np.stack([a, d, c], -2).reshape(-1, 3, 3)])


@pytest.mark.parametrize("scene, n", [("height field", 512), ("height field", 2048), ("32 stacked quads", 1024)])
def test_raster_depth_map_peak_memory_is_within_its_budget(scene, n):
    """tracemalloc's peak while rasterising (numpy reports its buffers to it) is the map's 8 bytes a texel
    plus a working set of texel-triangle pairs that the chunks bound, whatever the map size or the number
    of triangles covering a texel: never above depth_map.map_cost's bytes."""
    import tracemalloc
    if scene == "height field":
        tris = _height_field()
    else:
        quad = np.array([[[-3, -3, 0], [3, -3, 0], [3, 3, 0]], [[-3, -3, 0], [3, 3, 0], [-3, 3, 0]]], float)
        tris = np.concatenate([quad + (0, 0, 0.05 * k) for k in range(32)])
    w2v, proj, _, _ = _look_down((0.0, 0.0, 5.0), ortho=6.0)
    stats = {}
    tracemalloc.start()
    try:
        depth = raster.rasterize_depth(tris, w2v, proj, n, n, 1e-3, 100.0, stats=stats)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (depth < camera.SKY_DEPTH).all()                                # every texel covered
    assert stats["fragments"] >= (32 if "quads" in scene else 1) * n * n
    budget_bytes, _ = depth_map.map_cost(n, 1, "raster")
    assert 8 * n * n <= peak <= budget_bytes, (peak, budget_bytes)
    assert peak - 8 * n * n <= raster.CHUNK * depth_map.RASTER_BYTES_PER_PAIR


def test_shadow_map_budget_follows_the_depth_source(monkeypatch):
    """With 8 GiB usable: one raster map of 16384² (2 GiB) is accepted where a Cycles render of it (120 B a
    texel) is refused; six raster faces (12 GiB) are refused in one line naming the largest size that fits,
    N = floor(sqrt((8 GiB - frame - working set) / (6 x 8 B))), which fits while N + 1 does not."""
    from addon.core import budget
    memory = 8 << 30
    monkeypatch.setattr(budget, "memory_budget", lambda: memory)
    frame = 128 * 128 * depth_map.BYTES_PER_PIXEL
    depth_map.check_cost(128, 128, 16384, 1, "raster")
    with pytest.raises(InputError) as e:
        depth_map.check_cost(128, 128, 16384, 1, "cycles")
    assert f"the largest shadow-map size that fits is {math.isqrt((memory - frame) // 128)}" in str(e.value)
    with pytest.raises(InputError) as e:
        depth_map.check_cost(128, 128, 16384, 6, "raster")
    msg = str(e.value)
    best = math.isqrt((memory - frame - raster.CHUNK * depth_map.RASTER_BYTES_PER_PAIR) // 48)
    assert "\n" not in msg and msg.startswith("shadow-map size 16384 (6 maps from the raster depth source, "
                                              "128x128 pixels) needs about 12.2 GiB of memory (8 GiB usable here)")
    assert msg.endswith(f"the largest shadow-map size that fits is {best}")
    depth_map.check_cost(128, 128, best, 6, "raster")
    with pytest.raises(InputError):
        depth_map.check_cost(128, 128, best + 1, 6, "raster")
    with pytest.raises(InputError, match="unknown depth source 'gpu'"):
        depth_map.check_cost(128, 128, 64, 1, "gpu")


def test_off_plane_measures_how_far_a_receiver_leaves_its_plane():
    from addon.core.shadow.planar import off_plane, plane_from_point_normal
    plane = plane_from_point_normal((0, 0, 1), (0, 0, 2))
    quad = [(0, 0, 1), (3, 0, 1), (3, 4, 1), (0, 4, 1)]
    assert off_plane(quad, plane) == (0.0, 5.0)
    dome = quad + [(1.5, 2.0, 1.25)]
    distance, extent = off_plane(dome, plane)
    assert distance == 0.25 and abs(extent - np.sqrt(25 + 0.25 ** 2)) < 1e-12
