"""Shadow mapping (seed 003 "Shadow mapping"; Williams 1978; REFERENCE.md §4).

A depth map is rendered from the light (orthographic for a sun, perspective for a spot, six
90° cube faces for a point light): rasterised from the scene's triangles (:func:`rasterize`) or
read from a Cycles Depth pass; both give the planar view depth of the nearest surface through
each texel centre. A receiver point p with light-view depth d_p is in shadow
where d_p - b > z_map(texel(p)), with the bias b = b_c + b_s · texel(d_p) · tan θ:
constant b_c (metres) plus slope-scaled b_s (in texels) times the world size of a map texel
at that depth times tan θ, θ the angle between the normal and the light direction. Percentage
closer filtering (Reeves et al. 1987) averages the K×K nearest-texel comparisons around p.
"""
import numpy as np

from .. import budget
from ..camera import world_to_pixels
from ..errors import InputError
from .raster import CHUNK, rasterize_depth

#: tan θ is clamped here (θ about 84°) so grazing receivers get a finite bias.
MAX_TAN = 10.0

#: Limits shared by the script, the panel and the lab: render width, shadow-map size N.
MAX_RESOLUTION = 8192
MAX_SIZE = 16384
#: Cost estimates of a comparison (measured on 2 cores, rounded up; README "Limits"): peak bytes per
#: camera pixel (Cycles' passes, the float64 per-pixel arrays; 550 measured at 1024²) and bytes kept per
#: texel of each map (float64 depth).
BYTES_PER_PIXEL = 800
BYTES_PER_TEXEL_KEPT = 8
#: Depth source "cycles": peak bytes per texel while Cycles renders one map (80 measured at 4096²) and
#: Cycles seconds per map texel (0.4-0.6e-6 measured).
BYTES_PER_TEXEL_RENDER = 120
SECONDS_PER_TEXEL = 1e-6
#: Depth source "raster" (core.shadow.raster.rasterize_depth; tracemalloc peaks and times on 2 cores at load
#: 3.5-6, 512²-16384², 10k-triangle scenes with 1.0-1.1 covered triangles per texel and 32 stacked quads with
#: 32): nothing per texel beyond the 8 bytes of the map it fills; about 60 bytes per texel-triangle pair in
#: flight (rows, spans, fragments), at most raster.CHUNK pairs at once (working set 20-120 MiB measured,
#: growing with the map's rows); seconds per texel and per covered texel-triangle pair (fit: 12 and 11 ns).
RASTER_BYTES_PER_PAIR = 80
RASTER_SECONDS_PER_TEXEL = 3e-8
RASTER_SECONDS_PER_PAIR = 3e-8
#: Covered triangles per map texel a raster's time is planned for (the built-in scenes have 0.6-1.1); even so
#: six 16384² faces take about 30 min of the 2-hour limit: the raster's bound is memory.
RASTER_PAIRS_PER_TEXEL = 32
#: Where a shadow map's depth comes from: the numpy rasteriser (default) or Cycles' Depth pass.
DEPTH_SOURCES = ("raster", "cycles")


def check_source(source):
    """``source`` if it is one of DEPTH_SOURCES, else InputError."""
    if source not in DEPTH_SOURCES:
        raise InputError(f"unknown depth source '{source}' (choose from {', '.join(DEPTH_SOURCES)})")
    return source


def map_cost(size, faces=1, source="raster"):
    """(bytes, seconds) of ``faces`` depth maps of ``size``² texels from ``source``, beyond the frame.

    raster: 8 faces N² + CHUNK RASTER_BYTES_PER_PAIR bytes, faces N² (t_texel + RASTER_PAIRS_PER_TEXEL t_pair)
    seconds; cycles: N² (BYTES_PER_TEXEL_RENDER + 8 faces) bytes, faces N² SECONDS_PER_TEXEL seconds."""
    check_source(source)
    texels = faces * size * size
    if source == "cycles":
        return size * size * BYTES_PER_TEXEL_RENDER + texels * BYTES_PER_TEXEL_KEPT, texels * SECONDS_PER_TEXEL
    return (texels * BYTES_PER_TEXEL_KEPT + CHUNK * RASTER_BYTES_PER_PAIR,
            texels * (RASTER_SECONDS_PER_TEXEL + RASTER_PAIRS_PER_TEXEL * RASTER_SECONDS_PER_PAIR))


def check_cost(width, height, size=None, faces=1, source="raster"):
    """Refuse (InputError naming the largest value that fits) a frame of ``width`` x ``height`` pixels,
    or ``faces`` shadow maps of ``size``² texels from depth ``source`` (:func:`map_cost`), whose estimated
    memory or time does not fit."""
    aspect = height / width
    frame = lambda w: w * max(1, round(w * aspect)) * BYTES_PER_PIXEL  # noqa: E731
    budget.check("resolution", int(width), lambda w: (frame(w), 0.0), 8)
    check_source(source)
    if size:
        budget.check("shadow-map size", int(size),
                     lambda n: (frame(width) + map_cost(n, faces, source)[0], map_cost(n, faces, source)[1]), 2,
                     f"({faces} map{'s' if faces > 1 else ''} from the {source} depth source, {width}x{height} pixels)")


def check_pcf(k):
    """A PCF kernel size is a positive odd integer (1 = a single nearest-texel comparison)."""
    if int(k) != k or k < 1 or k % 2 == 0:
        raise InputError(f"PCF kernel size must be a positive odd integer, got {k}")
    return int(k)


def texel_size(depth, proj, size):
    """World width of one map texel at light-view depth d: 2/(N P00) orthographic, 2 d/(N P00) perspective."""
    ortho = abs(proj[3, 3] - 1.0) < 1e-9
    return (2.0 / (size * proj[0, 0])) * (1.0 if ortho else np.asarray(depth, np.float64))


def tan_theta(normals, to_light):
    """tan θ = sin θ / cos θ of the angle between unit normals and unit light directions, clamped."""
    c = np.clip(np.einsum("...i,...i->...", normals, to_light), 1e-6, 1.0)
    return np.minimum(np.sqrt(1.0 - c * c) / c, MAX_TAN)


def bias(depth, normals, to_light, proj, size, constant, slope):
    """b = b_c + b_s · texel(d) · tan θ (see the module docstring)."""
    return constant + slope * texel_size(depth, proj, size) * tan_theta(normals, to_light)


def pcf_lookup(depth_map, x, y, d, b, k):
    """Lit fraction in [0, 1]: mean over the K×K texels around (x, y) of [d - b <= z_map].

    Texels outside the map count as lit (a border depth at infinity).
    """
    k = check_pcf(k)
    h, w = depth_map.shape
    cx = np.rint(x).astype(np.int64)
    cy = np.rint(y).astype(np.int64)
    r = k // 2
    lit = np.zeros(np.shape(d), np.float64)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            tx, ty = cx + dx, cy + dy
            inside = (tx >= 0) & (tx < w) & (ty >= 0) & (ty < h)
            z = depth_map[np.clip(ty, 0, h - 1), np.clip(tx, 0, w - 1)]
            lit += np.where(inside, (d - b) <= z, True)
    return lit / (k * k)


class DepthMap:
    """One depth image rendered from the light: (H, W) planar view depth, the view matrix and projection."""

    def __init__(self, depth, world_to_view, proj):
        self.depth = np.asarray(depth, np.float64)
        self.world_to_view = np.asarray(world_to_view, np.float64)
        self.proj = np.asarray(proj, np.float64)
        if self.depth.ndim != 2 or self.depth.shape[0] != self.depth.shape[1]:
            raise InputError("a shadow map must be a square depth image")

    @property
    def size(self):
        return self.depth.shape[0]

    def project(self, points):
        """Texel coordinates (x, y) and light-view depth of world points."""
        return world_to_pixels(points, self.world_to_view, self.proj, self.size, self.size)


def rasterize(tris, world_to_view, proj, size, near, far=np.inf, stats=None):
    """A :class:`DepthMap` of ``size``² texels of world triangles (T, 3, 3) seen by the light camera
    ``world_to_view``, ``proj`` with clip range [near, far] (core.shadow.raster.rasterize_depth)."""
    return DepthMap(rasterize_depth(tris, world_to_view, proj, size, size, near, far, stats=stats),
                    world_to_view, proj)


def select_faces(maps, points):
    """Index of the map each point falls in: the one whose NDC |x|, |y| is smallest with the point in front."""
    best = np.full(len(points), np.inf)
    idx = np.zeros(len(points), np.int64)
    for i, m in enumerate(maps):
        x, y, d = m.project(points)
        n = m.size
        spread = np.maximum(np.abs((x + 0.5) / n * 2 - 1), np.abs((y + 0.5) / n * 2 - 1))
        spread = np.where(d > 0, spread, np.inf)
        better = spread < best
        best = np.where(better, spread, best)
        idx = np.where(better, i, idx)
    return idx


def lit_fraction(maps, points, normals, to_light, constant_bias=0.0, slope_bias=0.0, pcf=1):
    """Shadow-map visibility (lit fraction) of (N, 3) world points with (N, 3) unit normals.

    ``maps``: one :class:`DepthMap` (sun, spot) or six cube faces (point light);
    ``to_light``: (N, 3) unit vectors from each point toward the light.
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    out = np.ones(len(points))
    face = select_faces(maps, points) if len(maps) > 1 else np.zeros(len(points), np.int64)
    for i, m in enumerate(maps):
        sel = face == i
        if not sel.any():
            continue
        x, y, d = m.project(points[sel])
        b = bias(d, normals[sel], to_light[sel], m.proj, m.size, constant_bias, slope_bias)
        out[sel] = pcf_lookup(m.depth, x, y, d, b, pcf)
    return out
