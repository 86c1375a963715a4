"""Analytic G-buffers for the SSAO core tests: rays cast in numpy against planes (no bpy).

The closed form of the corner (REFERENCE.md §3 with an AO distance R) is core.analytic.corner_k_a;
its disk segment and quadrant are checked here against Monte Carlo on the disk and against the
limits REFERENCE.md §3 states.
"""
import numpy as np
import pytest

from addon.core import camera
from addon.core import analytic
from addon.core.camera import SKY_DEPTH
from addon.core.ssao.gbuffer import GBuffer


def look_at(eye, target):
    """world_to_view of a camera at ``eye`` looking at ``target`` (+Z up), Blender's convention."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = right, up, back, eye
    return np.linalg.inv(c2w)


def perspective(lens=50.0, sensor=36.0, near=0.05, far=200.0):
    """Blender's calc_matrix_camera for a square frame (sensor fit AUTO)."""
    f = 2.0 * lens / sensor
    return np.array([[f, 0, 0, 0], [0, f, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
                     [0, 0, -1, 0]], float)


def render(planes, eye, target, size, lens=50.0):
    """``planes``: [(point, normal, inside(points) -> bool)]; returns (GBuffer, world positions, plane id)."""
    w2v, proj = look_at(eye, target), perspective(lens)
    o, d = camera.pixel_rays(w2v, proj, size, size)
    best = np.full(o.shape[:2], np.inf)
    pid = np.full(o.shape[:2], -1)
    nrm = np.zeros(o.shape)
    for i, (p0, n, inside) in enumerate(planes):
        p0, n = np.asarray(p0, float), np.asarray(n, float)
        denom = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((p0 - o) @ n) / denom
        hit = o + t[..., None] * d
        ok = (t > 0) & np.isfinite(t) & inside(hit) & (t < best)
        best[ok] = t[ok]
        pid[ok] = i
        nrm[ok] = n
    mask = pid >= 0
    world = o + np.where(mask, best, 0.0)[..., None] * d
    pos = (world @ w2v[:3, :3].T + w2v[:3, 3]).astype(np.float32)
    nv = (nrm @ w2v[:3, :3].T).astype(np.float32)
    depth = np.where(mask, -pos[..., 2], SKY_DEPTH).astype(np.float32)
    pos[~mask] = 0
    nv[~mask] = 0
    return GBuffer(pos, nv, depth, mask, proj), world, pid


def floor_only(size=64, eye=(0.0, -6.0, 1.5), target=(0.0, 0.0, 0.0)):
    """An infinite floor z = 0 seen from 1.5 m up, 6 m away: sky at the top of the frame."""
    return render([((0, 0, 0), (0, 0, 1), lambda p: np.ones(p.shape[:-1], bool))], eye, target, size)


def corner(size=64, eye=(4.0, 3.5, 2.8), target=(0.6, 0.5, 0.3)):
    """Floor z = 0 (x, y >= 0) and two infinite walls x = 0, y = 0 (z >= 0): a room corner."""
    eps = -1e-9
    planes = [((0, 0, 0), (0, 0, 1), lambda p: (p[..., 0] >= eps) & (p[..., 1] >= eps)),
              ((0, 0, 0), (1, 0, 0), lambda p: (p[..., 1] >= eps) & (p[..., 2] >= eps)),
              ((0, 0, 0), (0, 1, 0), lambda p: (p[..., 0] >= eps) & (p[..., 2] >= eps))]
    return render(planes, eye, target, size)


def corner_k_a(world, pid, radius):
    """Closed-form k_A with AO distance R at the corner's pixels: distances to the two other planes."""
    x, y, z = world[..., 0], world[..., 1], world[..., 2]
    a = np.choose(np.maximum(pid, 0), [x, y, x]) / radius
    b = np.choose(np.maximum(pid, 0), [y, z, z]) / radius
    return np.where(pid >= 0, analytic.corner_k_a(a, b), 1.0)


# ------------------------------------------------------------------ the oracles themselves (core.ssao)
segment, quadrant = analytic.disk_segment, analytic.disk_quadrant


def test_segment_and_quadrant_match_monte_carlo_on_the_disk():
    rng = np.random.default_rng(1)
    p = rng.random((400000, 2)) * 2 - 1
    p = p[(p ** 2).sum(1) <= 1]
    n = len(p)
    for a, b in [(0.0, 0.0), (0.3, 0.5), (0.7, 0.1), (0.9, 0.6)]:
        frac = np.mean(p[:, 0] > a)
        assert abs(segment(a) / np.pi - frac) < 4 * np.sqrt(frac * (1 - frac) / n) + 1e-4
        frac = np.mean((p[:, 0] > a) & (p[:, 1] > b))
        assert abs(quadrant(a, b) / np.pi - frac) < 4 * np.sqrt(frac * (1 - frac) / n) + 1e-4


def test_closed_forms_reduce_to_reference_section_3():
    # wall through the point: k_A = 1/2; corner of two walls: 1/4; wall beyond R: 1
    assert 1 - segment(0.0) / np.pi == 0.5
    assert abs(1 - (2 * segment(0.0) - quadrant(0.0, 0.0)) / np.pi - 0.25) < 1e-12
    assert 1 - segment(1.0) / np.pi == 1.0
    # R -> infinity: a wall at any finite distance blocks half the hemisphere, as the long-wall form
    # F = (1 - d/sqrt(d^2 + H^2))/2 gives for H -> infinity
    assert abs(segment(1e-6) / np.pi - 0.5) < 1e-6
    assert analytic.corner_k_a(0.0, 0.0) == pytest.approx(0.25) and analytic.corner_k_a(0.0, 1.0) == pytest.approx(0.5)
