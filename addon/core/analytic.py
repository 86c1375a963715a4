"""Closed forms used as test oracles and reference values: no approximation in them.

SSAO: the disk areas behind the open fraction of a corner (REFERENCE.md §3 with an AO distance R).
Radiosity: the built-in Cornell-box-like room, the reference scene of the tests and of the lab's
"Build Cornell box" button.
Environment maps: the linear sky L(l) = a + b (l·z), its irradiance and its Phong-prefiltered map.
"""
import numpy as np

from .envmap.latlong import latlong_directions
from .radiosity.patches import patches_from_meshes
from .radiosity.subdivision import subdivide_to_size


def disk_segment(c):
    """Area of the unit disk where x > c (0 <= c <= 1): acos c - c√(1 - c²)."""
    c = np.clip(c, 0.0, 1.0)
    return np.arccos(c) - c * np.sqrt(1.0 - c * c)


def disk_quadrant(a, b):
    """Area of the unit disk where x > a and y > b (a, b >= 0): ∫_a^t (√(1 - x²) - b) dx, t = √(1 - b²)."""
    a, b = np.clip(a, 0.0, 1.0), np.clip(b, 0.0, 1.0)
    top = np.sqrt(np.clip(1.0 - b * b, 0.0, 1.0))

    def g(t):      # ∫ √(1 - x²) dx
        return 0.5 * (t * np.sqrt(np.clip(1 - t * t, 0, 1)) + np.arcsin(np.clip(t, -1, 1)))
    return np.where(a < top, g(top) - g(a) - b * (top - a), 0.0)


def corner_k_a(a, b):
    """k_A, AO distance R, of a point at distances a R and b R from two perpendicular infinite planes
    meeting at a right angle to its own surface (a room's floor by two walls; a = ∞ for one wall).

    A cosine-weighted direction projects uniformly onto the unit disk of the tangent plane
    (Nusselt); the plane at distance d blocks, within R, exactly the directions whose component
    toward it exceeds d/R: a disk segment. Two planes block the union of two segments:
    k_A = 1 - (seg(a) + seg(b) - quad(a, b))/π. R -> ∞ gives REFERENCE.md §3's 1/2 (one wall
    through the point) and 1/4 (the corner).
    """
    return 1.0 - (disk_segment(a) + disk_segment(b) - disk_quadrant(a, b)) / np.pi


def cornell_box(light_radiance=15.0, size=2.0):
    """A closed Cornell-box-like room (x, y in [−s/2, s/2], z in [0, s]) with a square ceiling light and two
    rotated boxes, as ``patches_from_meshes`` input. Walls face inward, boxes outward; white 0.7, red, green."""
    h = size / 2
    white, red, green = (0.7, 0.7, 0.7), (0.65, 0.08, 0.06), (0.12, 0.55, 0.1)
    L = 0.25 * size / 2
    meshes = []

    def quad(name, verts, rho, emission=(0.0, 0.0, 0.0)):
        meshes.append({"name": name, "vertices": np.array(verts, float), "faces": [(0, 1, 2, 3)],
                       "rho": rho, "emission": emission})

    s = size
    quad("Floor", [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], white)
    quad("Back", [(-h, h, 0), (h, h, 0), (h, h, s), (-h, h, s)], white)
    quad("Front", [(-h, -h, 0), (-h, -h, s), (h, -h, s), (h, -h, 0)], white)
    quad("Left", [(-h, -h, 0), (-h, h, 0), (-h, h, s), (-h, -h, s)], red)
    quad("Right", [(h, -h, 0), (h, -h, s), (h, h, s), (h, h, 0)], green)
    # ceiling: a 3x3 grid around the light, facing down
    xs = [-h, -L, L, h]
    verts, faces = [], []
    for j in range(4):
        for i in range(4):
            verts.append((xs[i], xs[j], s))
    for j in range(3):
        for i in range(3):
            if i == 1 and j == 1:
                continue
            a = j * 4 + i
            faces.append((a, a + 4, a + 5, a + 1))
    meshes.append({"name": "Ceiling", "vertices": np.array(verts), "faces": faces, "rho": white,
                   "emission": (0.0, 0.0, 0.0)})
    quad("Light", [(-L, -L, s), (-L, L, s), (L, L, s), (L, -L, s)], (0.0, 0.0, 0.0),
         (light_radiance,) * 3)
    meshes.append(_box("ShortBox", (0.3 * s / 2, -0.25 * s / 2), 0.3 * s, 0.3 * s, np.radians(-17), white))
    meshes.append(_box("TallBox", (-0.3 * s / 2, 0.3 * s / 2), 0.3 * s, 0.6 * s, np.radians(17), white))
    return meshes


def _box(name, xy, side, height, angle, rho):
    c, s = np.cos(angle), np.sin(angle)
    e = side / 2
    base = [(-e, -e), (e, -e), (e, e), (-e, e)]
    pts = [(xy[0] + c * x - s * y, xy[1] + s * x + c * y) for x, y in base]
    verts = [(x, y, 0.0) for x, y in pts] + [(x, y, height) for x, y in pts]
    faces = [(4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return {"name": name, "vertices": np.array(verts), "faces": faces, "rho": rho, "emission": (0.0, 0.0, 0.0)}


def cornell_patches(max_edge=0.25, light_radiance=15.0):
    """The built-in scene split into patches no longer than ``max_edge``."""
    return subdivide_to_size(patches_from_meshes(cornell_box(light_radiance)), max_edge)


def linear_sky(h, w, a, b):
    """L(l) = a + b (l·z) (REFERENCE.md §3) as a lat-long map (h, w, 3); a and b scalars or RGB."""
    z = latlong_directions(h, w)[..., 2:3]
    return (np.asarray(a, np.float64) + np.asarray(b, np.float64) * z) * np.ones(3)


def linear_sky_irradiance(normals, a, b):
    """Closed form of the linear sky: E(n) = πa + (2π/3) b (n·z) for every n."""
    nz = np.asarray(normals, np.float64)[..., 2:3]
    return (np.pi * np.asarray(a, np.float64) + 2 * np.pi / 3 * np.asarray(b, np.float64) * nz) * np.ones(3)


def linear_sky_prefiltered(r, a, b, n):
    """Closed form of the Phong-prefiltered linear sky: G(r) = a + b ((n+1)/(n+2)) (r·z)."""
    rz = np.asarray(r, np.float64)[..., 2:3]
    return (np.asarray(a, np.float64) + np.asarray(b, np.float64) * (n + 1) / (n + 2) * rz) * np.ones(3)
