"""core.camera: the one pixel convention (row 0 at the top, pixel centres at integers)."""
import numpy as np

from addon.core import camera


def test_pixels_and_ndc_are_inverse_and_centre_the_corner_pixel():
    w, h = 7, 5
    assert np.allclose(camera.pixels_to_ndc(0, 0, w, h), (-1 + 1 / w, 1 - 1 / h))
    assert np.allclose(camera.pixels_to_ndc(w - 1, h - 1, w, h), (1 - 1 / w, -1 + 1 / h))
    x, y = np.random.default_rng(0).uniform(-0.5, 9.5, (2, 100))
    assert np.allclose(camera.ndc_to_pixels(*camera.pixels_to_ndc(x, y, w, h), w, h), (x, y), atol=1e-12)


def test_pixel_rays_hit_the_points_that_project_to_their_pixels():
    w, h = 6, 4
    f = 2.0
    proj = np.array([[f * h / w, 0, 0, 0], [0, f, 0, 0], [0, 0, -1.002, -0.2002], [0, 0, -1, 0]])
    world_to_view = np.eye(4)
    world_to_view[:3, 3] = (0.3, -0.2, -1.0)
    o, d = camera.pixel_rays(world_to_view, proj, w, h)
    x, y, depth = camera.world_to_pixels(o + 3.0 * d, world_to_view, proj, w, h)
    ys, xs = np.mgrid[0:h, 0:w]
    assert np.allclose(x, xs, atol=1e-9) and np.allclose(y, ys, atol=1e-9) and (depth > 0).all()
