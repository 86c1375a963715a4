"""The physics and the maths of Illumination Lab: numpy only, never bpy.

Submodules are imported by name (``from addon.core import exr``); importing the
package itself pulls in nothing but numpy-free Python.
"""
