"""Render passes reach numpy on the camera's pixel grid (the labs' shared ground)."""
import numpy as np
import pytest

from addon.core import camera as cam
from addon.blender import render
from addon.blender import scene as sc

pytestmark = pytest.mark.both_versions


def test_position_pass_projects_back_onto_its_own_pixels():
    scene = sc.new_scene("T", (48, 32))
    sc.plane(scene, "Floor", 6.0)
    sc.sphere(scene, "Ball", 0.7, location=(0.3, 0.0, 0.7), segments=24, rings=12)
    sc.camera(scene, "Cam", (1.0, -5.0, 3.0), target=(0.0, 0.0, 0.3))
    sc.world(scene, strength=1.0)
    vl = scene.view_layers[0]
    vl.use_pass_position = True
    vl.use_pass_z = True
    w2v, proj, w, h = render.camera_matrices(scene)
    render.cycles_cpu(scene, samples=1)
    scene.cycles.filter_width = 0.01
    passes = render.render_layers(scene)
    pos = passes["Position"][..., :3]
    assert pos.shape == (32, 48, 3)
    hit = np.isfinite(pos).all(-1) & (np.abs(pos).sum(-1) > 0)
    x, y, depth = cam.world_to_pixels(pos[hit], w2v, proj, w, h)
    ys, xs = np.nonzero(hit)
    assert np.max(np.abs(x - xs)) < 0.5 and np.max(np.abs(y - ys)) < 0.5
    np.testing.assert_allclose(depth, passes["Depth"][hit], rtol=1e-3)
