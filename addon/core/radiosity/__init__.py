"""Radiosity on patches, numpy only (seed 004; Goral et al. 1984; Cohen et al. 1988; REFERENCE.md §3).

patches       the Patches list: polygons as quads, area, normal, centroid, back sides
subdivision   splitting to a size, near emitters (graded) and where the solution changes fast
cost          the patch count, memory and time of a solve, refused before allocating
form_factors  point-to-polygon (Lambert), patch-to-patch and near-field form factors
visibility    visibility rays between patches against the scene's faces (clustered), or brute force
solvers       direct, Jacobi, Gauss-Seidel and progressive solvers of B = E + ρ F B
atlas         per-vertex values and the light-map atlas

The built-in Cornell box (the tests' reference scene) is in core/analytic.py.
"""
