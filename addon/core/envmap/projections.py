"""Cube maps and sphere maps from and to lat-long maps."""
import numpy as np

from .latlong import latlong_directions, sample_latlong


#: Face order and, per face, (major axis, sign, s axis and sign, t axis and sign): the OpenGL
#: cube-map table applied to Blender world axes. s runs along columns, t along rows (row 0 = t 0).
CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
_CUBE_TABLE = (  # (major, sign, sc_axis, sc_sign, tc_axis, tc_sign)
    (0, 1, 2, -1, 1, -1), (0, -1, 2, 1, 1, -1),
    (1, 1, 0, 1, 2, 1), (1, -1, 0, 1, 2, -1),
    (2, 1, 0, 1, 1, -1), (2, -1, 0, -1, 1, -1),
)


def direction_to_cube(d):
    """Directions (…, 3) -> (face index, s, t) with s, t in [0, 1] (OpenGL's selection by major axis)."""
    d = np.asarray(d, np.float64)
    a = np.abs(d)
    major = np.argmax(a, axis=-1)
    sign = np.take_along_axis(d, major[..., None], -1)[..., 0] >= 0
    face = 2 * major + (~sign)
    s = np.empty(d.shape[:-1])
    t = np.empty(d.shape[:-1])
    for f, (ax, sg, sa, ss, ta, ts) in enumerate(_CUBE_TABLE):
        m = face == f
        ma = a[..., ax][m]
        s[m] = (ss * d[..., sa][m] / ma + 1) / 2
        t[m] = (ts * d[..., ta][m] / ma + 1) / 2
    return face, s, t


def cube_to_direction(face, s, t):
    """Inverse of :func:`direction_to_cube`: unit directions (…, 3)."""
    face = np.asarray(face)
    sc, tc = 2 * np.asarray(s, np.float64) - 1, 2 * np.asarray(t, np.float64) - 1
    d = np.zeros(np.broadcast(face, sc).shape + (3,))
    for f, (ax, sg, sa, ss, ta, ts) in enumerate(_CUBE_TABLE):
        m = np.broadcast_to(face == f, d.shape[:-1])
        d[..., ax][m] = sg
        d[..., sa][m] = np.broadcast_to(ss * sc, m.shape)[m]
        d[..., ta][m] = np.broadcast_to(ts * tc, m.shape)[m]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cube_face_directions(size):
    """(6, size, size, 3) directions of every cube-map texel centre, faces in :data:`CUBE_FACES` order."""
    st = (np.arange(size) + 0.5) / size
    t, s = np.meshgrid(st, st, indexing="ij")
    return np.stack([cube_to_direction(f, s, t) for f in range(6)])


def latlong_to_cube(env, size):
    """Lat-long (H, W, C) -> cube map (6, size, size, C) by bilinear lookup."""
    return sample_latlong(env, cube_face_directions(size))


def sample_cube(cube, d):
    """Nearest-texel lookup of a cube map (6, S, S, C) in directions (…, 3)."""
    size = cube.shape[1]
    face, s, t = direction_to_cube(d)
    i = np.clip((t * size).astype(np.int64), 0, size - 1)
    j = np.clip((s * size).astype(np.int64), 0, size - 1)
    return cube[face, i, j]


def cube_to_latlong(cube, width):
    """Cube map (6, S, S, C) -> lat-long (width/2, width, C) by nearest-texel lookup."""
    return sample_cube(cube, latlong_directions(width // 2, width))


def sphere_map_uv_to_direction(s, t):
    """Sphere map (mirror ball seen from −Y looking along +Y, X right, Z up; t = 1 at the top row).

    Eye frame (x, y, z) = world (X, Z, −Y). The ball normal at (s, t) is
    (2s − 1, 2t − 1, √(1 − …)) and the reflected direction r = 2 (n·e) n − e, e = (0, 0, 1).
    Returns (directions (…, 3), inside-the-disk mask).
    """
    x, y = 2 * np.asarray(s, np.float64) - 1, 2 * np.asarray(t, np.float64) - 1
    rr = x * x + y * y
    inside = rr <= 1.0
    nz = np.sqrt(np.clip(1.0 - rr, 0.0, None))
    re = np.stack([2 * nz * x, 2 * nz * y, 2 * nz * nz - 1], axis=-1)
    return np.stack([re[..., 0], -re[..., 2], re[..., 1]], axis=-1), inside


def direction_to_sphere_map_uv(d):
    """Inverse of :func:`sphere_map_uv_to_direction`: m = 2√(rx² + ry² + (rz + 1)²), s = rx/m + ½, t = ry/m + ½."""
    d = np.asarray(d, np.float64)
    rx, ry, rz = d[..., 0], d[..., 2], -d[..., 1]
    m = 2 * np.sqrt(rx * rx + ry * ry + (rz + 1) ** 2)
    behind = m <= 1e-12                               # r = +Y exactly: the rim; its top point stands for it
    m = np.where(behind, 1.0, m)
    return np.where(behind, 0.5, rx / m + 0.5), np.where(behind, 1.0, ry / m + 0.5)


def latlong_to_sphere_map(env, size):
    """Lat-long (H, W, C) -> sphere map (size, size, C); row 0 at the top. Texels outside the disk hold the
    rim's direction (+Y, behind the ball), so a bilinear lookup near the rim never mixes in black."""
    c = (np.arange(size) + 0.5) / size
    t, s = np.meshgrid(1.0 - c, c, indexing="ij")
    d, inside = sphere_map_uv_to_direction(s, t)
    d[~inside] = (0.0, 1.0, 0.0)
    return sample_latlong(env, d)


def sphere_map_to_latlong(sphere, width):
    """Sphere map (S, S, C) -> lat-long (width/2, width, C) by bilinear lookup inside the disk."""
    sphere = np.asarray(sphere, np.float64)
    size = sphere.shape[0]
    s, t = direction_to_sphere_map_uv(latlong_directions(width // 2, width))
    x = np.clip(s * size - 0.5, 0, size - 1)
    y = np.clip((1 - t) * size - 0.5, 0, size - 1)
    x0 = np.minimum(np.floor(x).astype(int), size - 2)
    y0 = np.minimum(np.floor(y).astype(int), size - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = sphere[y0, x0] * (1 - fx) + sphere[y0, x0 + 1] * fx
    bot = sphere[y0 + 1, x0] * (1 - fx) + sphere[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bot * fy
