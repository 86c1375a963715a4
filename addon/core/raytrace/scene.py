"""What the ray tracer sees: triangles with corner normals and a material each, point/spot/sun lights and a
constant background, in the units of REFERENCE.md §1 (a light's I = E⊥/π, surfaces return radiance)."""
import dataclasses

import numpy as np

from .. import brdf, lights as core_lights
from ..io.png import srgb_decode
from .bvh import BVH

#: Local models a material can use, with the core.brdf function and its parameter names.
MODELS = {
    "LAMBERT": (lambda n, l, v, I, kd=(0.8,) * 3: brdf.lambert(n, l, I, kd)),
    "PHONG": (lambda n, l, v, I, **p: brdf.phong(n, l, v, I, **p)),
    "BLINN_PHONG": (lambda n, l, v, I, **p: brdf.blinn_phong(n, l, v, I, **p)),
    "OREN_NAYAR": (lambda n, l, v, I, **p: brdf.oren_nayar(n, l, v, I, **p)),
    "COOK_TORRANCE": (lambda n, l, v, I, **p: brdf.cook_torrance(n, l, v, I, **p)),
}


@dataclasses.dataclass
class Material:
    """One surface. ``model``/``params``: the local model (core.brdf keyword arguments, k_a aside);
    ``ka``: ambient coefficient; ``mirror``: F0 of a perfect conductor mirror (k_s I_r) or None;
    ``ior``: index of a smooth glass (k_t I_t with F) or None; ``tint``: transmission colour; ``emission``: L_e
    (with the constant k_a I_a of a model whose parameters carry it); ``twin``: a callable (n, l, v, I, kd=None) ->
    radiance used instead of ``model`` (a shading model's numpy twin); ``texture``: k_d as an image (H, W, 3), linear,
    row 0 at the top, read through the triangles' UVs (:func:`sample_texture`) instead of the constant k_d;
    ``texture_srgb``: its texels are sRGB-encoded and decoded after filtering, as Cycles does with 8-bit images;
    ``texture_tint``: the factor k_d = texel × tint (1 − Metallic for a Principled BSDF);
    ``uv_map``: the UV layer that feeds it (the adapter's; "" = the render-active one)."""
    name: str = "default"
    model: str = "LAMBERT"
    params: dict = dataclasses.field(default_factory=lambda: {"kd": (0.8, 0.8, 0.8)})
    ka: float = 0.0
    mirror: tuple = None
    ior: float = None
    tint: tuple = (1.0, 1.0, 1.0)
    emission: tuple = (0.0, 0.0, 0.0)
    twin: object = None
    texture: object = None
    texture_srgb: bool = False
    texture_tint: tuple = (1.0, 1.0, 1.0)
    uv_map: str = None

    def local(self, n, l, v, I, kd=None):
        """I (k_d n·l + k_s (n·h)^n ...) of this material's model (seed 004 eq. 1-2, REFERENCE.md §2); ``kd`` (N, 3)
        replaces the constant k_d (a texture's texels at the hits)."""
        if self.twin is not None:
            return np.asarray(self.twin(n, l, v, I) if kd is None else self.twin(n, l, v, I, kd=kd), np.float64)
        if self.model not in MODELS:
            raise ValueError(f"unknown local model {self.model!r}")
        return MODELS[self.model](n, l, v, I, **(self.params if kd is None else {**self.params, "kd": kd}))

    @property
    def specular_only(self):
        return self.mirror is not None or self.ior is not None


def sample_texture(image, uv):
    """Bilinear lookup of ``image`` (H, W, C; row 0 at the top) at ``uv`` (N, 2) with repeat wrapping, as Cycles'
    Image Texture node with Linear interpolation and Repeat extension: texel centres at ((i + ½)/W, 1 − (j + ½)/H)."""
    h, w = image.shape[:2]
    x = np.asarray(uv[:, 0], np.float64) * w - 0.5
    y = (1.0 - np.asarray(uv[:, 1], np.float64)) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bot = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bot * fy


@dataclasses.dataclass
class Light:
    """A point, spot or sun light as Blender defines it: power P in W (strength S in W/m² for a sun),
    ``color``, ``position``, ``direction`` (where it points), ``cutoff`` = half the spot's cone angle."""
    kind: str
    power: float
    color: tuple = (1.0, 1.0, 1.0)
    position: tuple = (0.0, 0.0, 0.0)
    direction: tuple = (0.0, 0.0, -1.0)
    cutoff: float = np.pi / 4

    def sample(self, p):
        """(unit l toward the light, distance (inf for a sun), I) at points p: core.lights (REFERENCE.md §1)."""
        kind = self.kind.upper()
        if kind == "SUN":
            lvec, I = core_lights.sun_light(p, self.direction, self.color, self.power)
            dist = np.full(len(p), np.inf)
        elif kind == "POINT":
            lvec, I = core_lights.point_light(p, self.position, self.color, self.power)
            dist = np.linalg.norm(lvec, axis=-1)
        elif kind == "SPOT":
            lvec, I = core_lights.spot_light(p, self.position, self.direction, self.color, self.power, self.cutoff)
            dist = np.linalg.norm(lvec, axis=-1)
        else:
            raise ValueError(f"unknown light kind {self.kind!r}")
        l = lvec / np.maximum(np.linalg.norm(lvec, axis=-1, keepdims=True), 1e-300)
        return l, dist, np.asarray(I, np.float64)


class Scene:
    """Triangles (T, 3, 3), corner normals (T, 3, 3) (None: flat), material index per triangle, materials,
    lights, ambient light I_a (RGB) and the background radiance of rays that leave the scene. ``accel(tris)`` builds
    the intersection engine: an object with ``closest(o, d, tmin)`` -> (t, triangle or -1) and
    ``occluded(o, d, tmax, tmin)`` -> bool (core.raytrace.bvh.BVH, or Blender's BVHTree through the lab)."""

    def __init__(self, tris, material_index, materials, lights, normals=None, ambient=(0, 0, 0),
                 background=(0, 0, 0), accel=BVH, uvs=None):
        self.tris = np.asarray(tris, np.float64).reshape(-1, 3, 3)
        self.material_index = np.asarray(material_index, np.int64).reshape(-1)
        self.materials, self.lights = list(materials), list(lights)
        if len(self.material_index) != len(self.tris):
            raise ValueError("one material index per triangle")
        e1, e2 = self.tris[:, 1] - self.tris[:, 0], self.tris[:, 2] - self.tris[:, 0]
        ng = np.cross(e1, e2)
        self.face_normals = ng / np.maximum(np.linalg.norm(ng, axis=-1, keepdims=True), 1e-300)
        self.normals = (np.repeat(self.face_normals[:, None], 3, 1) if normals is None
                        else np.asarray(normals, np.float64).reshape(-1, 3, 3))
        self.uvs = None if uvs is None else np.asarray(uvs, np.float64).reshape(-1, 3, 2)
        self.ambient = np.asarray(ambient, np.float64)
        self.background = np.asarray(background, np.float64)
        lo, hi = (self.tris.reshape(-1, 3).min(0), self.tris.reshape(-1, 3).max(0)) if len(self.tris) else (0, 1)
        #: Ray offset off a surface: 1e-6 of the scene's size (at least 1e-7 m).
        self.epsilon = max(1e-6 * float(np.max(np.abs(np.r_[lo, hi]))), 1e-7)
        self.bvh = accel(self.tris)

    def barycentric(self, tri, p):
        """(N, 3) barycentric coordinates of points p in triangles ``tri``."""
        v = self.tris[tri]
        e1, e2, w = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0], p - v[:, 0]
        d00, d01, d11 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
        d20, d21 = (w * e1).sum(-1), (w * e2).sum(-1)
        den = np.where(np.abs(d00 * d11 - d01 ** 2) > 0, d00 * d11 - d01 ** 2, 1.0)
        b1 = (d11 * d20 - d01 * d21) / den
        b2 = (d00 * d21 - d01 * d20) / den
        return np.stack([1 - b1 - b2, b1, b2], axis=-1)

    def shading_normal(self, tri, p):
        """Corner normals interpolated with the barycentric coordinates of p in triangle ``tri`` (unit)."""
        n = np.einsum("nk,nkc->nc", self.barycentric(tri, p), self.normals[tri])
        return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)

    def albedo(self, mat, tri, p):
        """k_d (N, 3) of ``mat``'s texture at points p of triangles ``tri``, or None for a constant k_d."""
        if mat.texture is None or self.uvs is None:
            return None
        uv = np.einsum("nk,nkc->nc", self.barycentric(tri, p), self.uvs[tri])
        kd = sample_texture(mat.texture, uv)
        return (srgb_decode(kd) if mat.texture_srgb else kd) * np.asarray(mat.texture_tint, np.float64)
