"""The physics and the maths of Illumination Lab: numpy only, never bpy.

brdf, lights, lightmap, charts   shading models, light sources, light-map dilation, charts
camera, geometry                 pixel projection and sky depth; the ray–triangle intersection
analytic                         closed forms and reference scenes used as test oracles
budget, choices, errors          cost bounds, shared choices, domain errors
io/ shadow/ ssao/ envmap/ radiosity/   one package per area (see each package's docstring)

Submodules are imported by name (``from addon.core.io import exr``); importing the
package itself pulls in nothing but numpy-free Python.
"""
