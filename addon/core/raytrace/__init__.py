"""Ray casting and Whitted ray tracing in numpy (seed 004): a BVH, Snell/Fresnel optics, the recursion.

``scene.Scene`` holds triangles, materials and lights; ``whitted.trace(scene, origins, dirs, method,
max_depth)`` returns radiance per ray in the units of REFERENCE.md §1. No bpy.
"""
from .scene import Light, Material, Scene  # noqa: F401
from .whitted import METHODS, trace  # noqa: F401
