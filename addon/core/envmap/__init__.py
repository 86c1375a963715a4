"""Environment maps and irradiance environment maps, numpy only (seed 002; REFERENCE.md §3).

latlong      reading and checking lat-long maps, Blender's equirectangular directions, sampling
irradiance   E(n) by brute force, the sh9/brute switch and its cost bound
sh9          nine spherical-harmonic coefficients and the irradiance from them (Ramamoorthi & Hanrahan 2001)
prefilter    the Phong-prefiltered glossy map
projections  cube maps and sphere maps
maps         the three map types as images (cube strip, sphere map), lookups, texel solid angles and shape
reflection   reflection and refraction mapping: r, Snell's t (total internal reflection), Schlick's F

The .hdr codec is core/io/hdr.py; the linear sky and its closed forms (test oracles) are in core/analytic.py.
"""
