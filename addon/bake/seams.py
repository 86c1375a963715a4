"""The seam figure of a baked image map (:mod:`core.seams`) from the objects' evaluated meshes, and the stitch.

Seam edges are the edges of the evaluated mesh (what Cycles bakes; coincident vertices joined, as importers split
them at UV and normal borders) shared by two faces whose light-map UVs differ and whose corner normals agree (a
smooth surface: at a hard edge the shading itself jumps). The figure is measured
on the map as an engine's bilinear sampler reads it: before dilation, after it (and after denoising, which comes
first), and after the stitch, which runs when the jump after dilation is above the jump the bake's noise alone
gives (σ × the figure's noise factor, σ the map's estimated_error) or above the map's own variation between
neighbouring points inside the charts (the interior figure: the reference left after denoising, whose noise is not
estimated)."""
import math

import numpy as np

from ..blender.scene import corner_triangles, corner_uv, corner_vertices, positions, read
from ..core import lightmap, seams as core
from ..core.memo import FIGURES
from . import evaluated, uv as uvmod


def mesh_seams(obj, layer, depsgraph, width, height):
    """:class:`core.seams.Seams` of ``obj``'s evaluated mesh in UV layer ``layer``, in texels of a ``width`` ×
    ``height`` map; None when the evaluated mesh lacks the layer. Found once per object and map size while the
    layouts are fixed (every map kind of an object has the same seams)."""
    return uvmod.remembered(("seams", obj.as_pointer(), layer, width, height),
                            lambda: evaluated.figure(obj, depsgraph, _mesh_seams, layer, width, height))


def _mesh_seams(me, layer, width, height):
    if layer not in me.uv_layers:
        return None
    loops = corner_triangles(me).astype(np.int64)
    verts = corner_vertices(me)[loops]
    co = positions(me).astype(np.float64)
    uv = corner_uv(me, layer)
    normals = read(me.corner_normals, "vector", np.float32, 3)
    return FIGURES.call(_seam_edges, co, verts, loops, uv, normals, width, height)


def _seam_edges(co, verts, loops, uv, normals, width, height):
    """``core.seam_edges`` of a mesh's arrays (loop-triangle vertices and loops, per-loop UVs and normals)."""
    uv = uv.reshape(-1, 2).astype(float) * (width, height)
    return core.seam_edges(core.welded(co)[verts].reshape(-1, 3), uv[loops].reshape(-1, 3, 2),
                           normals.reshape(-1, 3)[loops].reshape(-1, 3, 3))


def _number(x, digits=6):
    return None if x is None or not math.isfinite(x) else float(f"{x:.{digits}g}")


def _joined(parts):
    parts = [s for s in parts if s is not None and len(s)]
    if not parts:
        return None
    return core.Seams(*(np.concatenate([getattr(s, k) for s in parts]) for k in ("a", "b", "a_in", "b_in")))


def seam_step(scene, group, layers, raw, mask, values, grow, sigma, value_range, fix=True, source=None):
    """Measure the seams of the map of ``group`` and stitch them when needed; return (values, {object: report
    "seams" entry}, EXR header attributes). ``raw`` the baked (and denoised) values, 0 off ``mask``; ``values`` the
    map after dilation by ``grow`` texels; ``sigma`` its estimated error per texel (NaN: not estimated, the interior
    figure is then the reference); stitched values are clipped to the kind's ``value_range``; ``fix`` False only
    measures; ``source`` the dilation's :func:`lightmap.dilation_source` (found here when None)."""
    h, w = mask.shape
    depsgraph = scene.view_layers[0].depsgraph
    found = {o.name: mesh_seams(o, layers[o.name], depsgraph, w, h) for o in group}
    found = {k: s for k, s in found.items() if s is not None}
    if not found:
        return values, {}, {}
    source = (lightmap.dilation_source(mask, grow) if source is None else source).ravel()
    at = {k: core.sampling(s, mask) for k, s in found.items()}
    before = {k: core.measure(raw, s, mask, at=at[k]) for k, s in found.items()}
    dilated = {k: core.measure(values, s, mask, source, at=at[k]) for k, s in found.items()}
    noise = {k: sigma * f.noise_factor if math.isfinite(sigma) else float("nan") for k, f in dilated.items()}
    fixed = fix and any(f.samples and not f.rms <= min((x for x in (noise[k], f.interior_rms) if math.isfinite(x)),
                                                default=0.0) for k, f in dilated.items())
    after = dilated
    if fixed:
        lo, hi = value_range
        stitched = core.stitch(values, _joined(found.values()))
        if lo is not None or hi is not None:
            stitched = np.clip(stitched, lo, hi)
        values = stitched.astype(values.dtype)
        after = {k: core.measure(values, s, mask, source, at=at[k]) for k, s in found.items()}
    entries = {}
    for k, f in after.items():
        entries[k] = {"edges": f.edges, "samples": f.samples, "rms": _number(f.rms), "max": _number(f.max),
                      "interior_rms": _number(f.interior_rms), "noise": _number(noise[k]),
                      "undilated_rms": _number(before[k].rms), "fixed": fixed, "creases": f.creases}
        if fixed:
            entries[k]["unfixed_rms"] = _number(dilated[k].rms)
    samples = sum(f.samples for f in after.values())
    header = {}
    if samples:
        header["il:seam_rms"] = _number(math.sqrt(sum(f.samples * f.rms ** 2 for f in after.values() if f.samples)
                                                  / samples))
        header["il:seam_fixed"] = int(fixed)
    return values, entries, header
