"""What the ray tracer sees: triangles with corner normals and a material each, point/spot/sun lights and a
constant background, in the units of REFERENCE.md §1 (a light's I = E⊥/π, surfaces return radiance)."""
import dataclasses

import numpy as np

from .. import brdf, lights as core_lights
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
    (with the constant k_a I_a of a model whose parameters carry it); ``twin``: a callable (n, l, v, I) -> radiance
    used instead of ``model`` (a shading model's numpy twin)."""
    name: str = "default"
    model: str = "LAMBERT"
    params: dict = dataclasses.field(default_factory=lambda: {"kd": (0.8, 0.8, 0.8)})
    ka: float = 0.0
    mirror: tuple = None
    ior: float = None
    tint: tuple = (1.0, 1.0, 1.0)
    emission: tuple = (0.0, 0.0, 0.0)
    twin: object = None

    def local(self, n, l, v, I):
        """I (k_d n·l + k_s (n·h)^n ...) of this material's model (seed 004 eq. 1-2, REFERENCE.md §2)."""
        if self.twin is not None:
            return np.asarray(self.twin(n, l, v, I), np.float64)
        if self.model not in MODELS:
            raise ValueError(f"unknown local model {self.model!r}")
        return MODELS[self.model](n, l, v, I, **self.params)

    @property
    def specular_only(self):
        return self.mirror is not None or self.ior is not None


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
                 background=(0, 0, 0), accel=BVH):
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
        self.ambient = np.asarray(ambient, np.float64)
        self.background = np.asarray(background, np.float64)
        lo, hi = (self.tris.reshape(-1, 3).min(0), self.tris.reshape(-1, 3).max(0)) if len(self.tris) else (0, 1)
        #: Ray offset off a surface: 1e-6 of the scene's size (at least 1e-7 m).
        self.epsilon = max(1e-6 * float(np.max(np.abs(np.r_[lo, hi]))), 1e-7)
        self.bvh = accel(self.tris)

    def shading_normal(self, tri, p):
        """Corner normals interpolated with the barycentric coordinates of p in triangle ``tri`` (unit)."""
        v = self.tris[tri]
        e1, e2, w = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0], p - v[:, 0]
        d00, d01, d11 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
        d20, d21 = (w * e1).sum(-1), (w * e2).sum(-1)
        den = np.where(np.abs(d00 * d11 - d01 ** 2) > 0, d00 * d11 - d01 ** 2, 1.0)
        b1 = (d11 * d20 - d01 * d21) / den
        b2 = (d00 * d21 - d01 * d20) / den
        nc = self.normals[tri]
        n = (1 - b1 - b2)[:, None] * nc[:, 0] + b1[:, None] * nc[:, 1] + b2[:, None] * nc[:, 2]
        return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
