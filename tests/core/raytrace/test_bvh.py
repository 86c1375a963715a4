"""The BVH against brute force and closed forms: a sphere's hit distance, shadow rays."""
import numpy as np

from addon.core.raytrace.bvh import BVH, brute_closest


def uv_sphere(radius=1.0, centre=(0, 0, 0), segments=64, rings=32):
    """Triangles of a UV sphere (vertices on the sphere) and their count."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    P = np.stack([np.sin(th)[:, None] * np.cos(ph), np.sin(th)[:, None] * np.sin(ph),
                  np.cos(th)[:, None] * np.ones_like(ph)], -1) * radius + np.asarray(centre, float)
    a, b, c, d = P[:-1, :-1], P[:-1, 1:], P[1:, 1:], P[1:, :-1]
    tris = np.concatenate([np.stack([a, d, c], -2).reshape(-1, 3, 3), np.stack([a, c, b], -2).reshape(-1, 3, 3)])
    area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=-1)
    return tris[area > 1e-12]


def test_closest_hits_equal_brute_force_on_random_triangles():
    rng = np.random.default_rng(1)
    tris = rng.uniform(-1, 1, (400, 1, 3)) + rng.normal(0, 0.3, (400, 3, 3))
    o = rng.uniform(-2, 2, (500, 3))
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, tri = BVH(tris).closest(o, d)
    tb, trib = brute_closest(o, d, tris)
    hit = trib >= 0
    assert hit.sum() > 50
    assert np.array_equal(tri, trib)
    np.testing.assert_allclose(t[hit], tb[hit], rtol=1e-12)
    assert np.all(np.isinf(t[~hit]))


def test_sphere_hit_distance_is_the_closed_form_within_the_sagitta():
    """Rays from (0, 0, 5) toward points of the disc: t = 5 - sqrt(1 - b^2) (b the impact parameter), the
    mesh sitting inside the sphere by at most its sagitta 1 - cos(pi/rings)."""
    tris = uv_sphere(1.0, segments=128, rings=64)
    b = np.linspace(0, 0.9, 30)
    o = np.stack([b, np.zeros_like(b), np.full_like(b, 5.0)], -1)
    d = np.tile([0.0, 0.0, -1.0], (len(b), 1))
    t, tri = BVH(tris).closest(o, d)
    exact = 5.0 - np.sqrt(1 - b ** 2)
    sagitta = 1 - np.cos(np.pi / 64)
    assert np.all(tri >= 0)
    assert np.all(t >= exact - 1e-12) and np.all(t - exact < 3 * sagitta / np.sqrt(1 - b ** 2) + 1e-9)


def test_shadow_rays_see_the_sphere_between_point_and_light_only():
    bvh = BVH(uv_sphere(1.0))
    o = np.array([[0, 0, -3.0], [3, 0, -3.0], [0, 0, -3.0]])
    d = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0]])
    tmax = np.array([10.0, 10.0, 1.5])            # the third stops before the sphere
    assert bvh.occluded(o, d, tmax).tolist() == [True, False, False]


def test_empty_scene_misses_everything():
    t, tri = BVH(np.zeros((0, 3, 3))).closest(np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1)))
    assert np.all(tri == -1) and np.all(np.isinf(t))
