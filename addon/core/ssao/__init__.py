"""Screen-space ambient occlusion from a G-buffer, numpy only (seed 003; REFERENCE.md §1, §4).

gbuffer   the G-buffer (view-space position, normal, depth, mask) and lookups into it
samplers  tangent frames, ball and cosine-hemisphere samples, horizon slices
methods   crytek, hemisphere, hbao, gtao and run_method
blur      the depth- and normal-aware blur
metrics   errors against a reference, silhouettes, reference noise
limits    the lab's limits, cost estimates and scene names
figures   preview and error images of the lab

Closed forms of the corner used as test oracles are in core/analytic.py; the sky depth is core.camera.SKY_DEPTH.
"""
