"""The files of a baked map: EXR (header il:* attributes) and PNG preview, or a vertex EXR and the colour
attribute; the checks before writing and the report entries."""
import json

import bpy
import numpy as np

from ..core import errors, lightmap
from ..core.errors import ILError
from ..core.io import exr, png as io_png
from . import orientation, uv as uvmod, uvchecks
from .inputs import HASH_KEY, UV_DIGEST_KEY, layout_digest
from .kinds import KINDS
from .passes import flat
from .plan import file_stems, map_file
from .seams import seam_step


MIN_COVERAGE_TEXT = (f"covered texels >= {uvchecks.MIN_COVERAGE:g} x side^2 x chart_area (the charts' UV area inside "
                     "the unit square)")


def check_plausible(scene, name, group, kind, result):
    """For a kind whose 0 means "inside" (``zero_means_inside``): an AO map that is 0 on every covered texel
    (vertex) of objects whose faces look into the objects themselves
    (most face normals hit their own object: a surface wound inside out that :mod:`.orientation` could not turn,
    e.g. faces split apart) with nothing inside (no light, no other object: not a room) measures the empty inside
    of the object: refuse it instead of writing it."""
    if not KINDS[kind].zero_means_inside:
        return
    values = flat(result.values) if isinstance(result.values, dict) else result.values[result.mask]
    if values.size and float(np.max(values)) <= 0.0 and all(
            orientation.faces_into_itself(scene, o) > 0.5 and not orientation.holds_something(scene, o) for o in group):
        raise ILError(f"'{name}' {kind}: 0 on every {'texel' if result.mask is not None else 'vertex'}: its faces look "
                      f"into the object itself, so the bake measured its inside (normals pointing inward; "
                      f"{orientation.FIX}): nothing written")


def check_lit(scene, name, kind, result, world):
    """For a kind lights shade (``Kind.lit``): a map 0 on every covered texel (vertex) is right, E = 0, but no light,
    world or emission reaches the objects, which is rarely what was meant (a file without lights or world, lights
    hidden from render). Warn with what the scene lacks (``world``: its own, None when it has none) and keep the
    line on ``result.unlit`` (report entries' "unlit", header "il:unlit")."""
    if not KINDS[kind].lit:
        return
    values = flat(result.values) if isinstance(result.values, dict) else result.values[result.mask]
    if not values.size or float(np.max(values)) > 0.0:
        return
    lights = [o for o in scene.objects if o.type == "LIGHT" and not o.hide_render and o.data.energy > 0]
    lacks = [what for what, missing in (("no lights", not lights), ("no world", world is None)) if missing]
    cause = f"the scene has {' and '.join(lacks)}" if lacks else "its lights and world do not reach it"
    result.unlit = (f"'{name}' {kind}: 0 on every {'texel' if result.mask is not None else 'vertex'} ({cause}): "
                    f"add a light, or a world that is not black")
    errors.warn(result.unlit)


def check_covered(name, group, kind, result, layers, areas):
    """The baked mask must cover MIN_COVERAGE of the charts' area (never report an empty map as a success)."""
    h, w = result.mask.shape
    expected = sum(areas.values()) * w * h
    covered = int(result.mask.sum())
    if covered < uvchecks.MIN_COVERAGE * expected:
        raise ILError(f"'{name}' {kind}: Cycles covered {covered} texels of the {expected:.0f} its charts span "
                      f"(minimum {100 * uvchecks.MIN_COVERAGE:.0f} %): nothing written")


def _attributes(kind, result, options, uv_name):
    """The il:* header attributes of a map file that every target writes (the kind's quantity, units and, for
    a kind following the bounces, il:bounces); no timings, so the same inputs give the same file bytes."""
    record = KINDS[kind]
    return {"il:quantity": record.quantity, "il:units": record.units, "il:samples": result.samples,
            "il:ao_distance": options.ao_distance, "il:uv_layer": uv_name or "",
            "il:blender_version": bpy.app.version_string, "il:bounces": options.bounces if record.bounces else "",
            "il:denoised": int(bool(options.denoise and options.target == "image" and record.denoise)),
            "il:estimated_error": result.estimated_error, "il:error_estimate": result.estimate,
            "il:pilot_samples": int(result.pilot_samples)} | ({"il:unlit": result.unlit} if result.unlit else {})


def preview(kind, values, mask):
    """The 8-bit PNG preview of a map: the kind's display mapping, 0 outside ``mask``."""
    display = KINDS[kind].preview(values)
    display = np.where(mask[..., None] if display.ndim == 3 else mask, display, 0.0)
    return io_png.to_uint8(display)


def entry(path, res, result, extra=None):
    """One bake_report.json entry (DESIGN.md keys first; "error_estimate" says what estimated_error is)."""
    e = {"file": path, "resolution": list(res), "samples": int(result.samples), "seconds": round(result.seconds, 4),
         "estimated_error": None if not np.isfinite(result.estimated_error) else float(result.estimated_error),
         "error_estimate": result.estimate, "cycles_seconds": round(result.cycles_seconds, 4)}
    if result.pilot_samples:
        e["pilot_samples"] = int(result.pilot_samples)
    if getattr(result, "capped", False):
        e["capped"] = True
    if getattr(result, "unlit", ""):
        e["unlit"] = result.unlit
    e.update(extra or {})
    return e


def _finite(name, kind, values):
    """A map with NaN or Inf is an error, not a file."""
    every = flat(values) if isinstance(values, dict) else values
    if not np.all(np.isfinite(every)):
        raise ILError(f"'{name}' {kind}: the baked values are not finite (NaN or Inf, e.g. from an emission or a "
                      f"light of infinite strength): nothing written")


#: The lines and figures a map keeps per object, in its report entries (key) and its header ("il:" + key, JSON
#: {object: value}), so that an entry rebuilt on resume keeps them: their JSON type.
PER_OBJECT = {"low_fill": str, "unwrap": str, "uv_cache": list, "unmapped": str, "inputs": dict}


def write_map(name, group, kind, result, out, options, layers, margin=None, overlap=None, digest=None, stems=None,
              scene=None, per_object=None, dilation=None):
    """Write the files of one baked map; return ``{object: report entry}``. ``margin``: the layout's margin in
    texels (default the asked one; the map is dilated by ``dilation`` texels, default :func:`uv.dilation`; both in
    the report and the header). ``overlap`` = ({object: fraction}, group fraction) of covered texels shared by several faces;
    ``stems`` the file stems of :func:`file_stems`; ``per_object`` {:data:`PER_OBJECT` key: {object: value}}: the
    :func:`uvchecks.low_fill` lines ("low_fill"), the unwrapper of a layout made in this run ("unwrap"), the (UV cache
    key, index) of layouts the UV cache holds ("uv_cache": an export finds the layer there), the
    :func:`uvchecks.check_unmapped` lines ("unmapped"), what in the scene the map was baked from ("inputs",
    :func:`inputs.scene_inputs`), in the entries and the header. With ``scene``, the seams are
    measured and stitched when needed (:func:`seams.seam_step`: entries' "seams", header "il:seam_rms",
    "il:seam_fixed" and "il:seams", the entries' figures by object, so an entry rebuilt on resume keeps them)."""
    stems = stems or file_stems()
    if options.target != "image":
        return _write_vertices(group, kind, result, out, options, digest, stems)
    margin = uvmod.margin_value(options.margin if margin is None else margin)
    grow = uvmod.dilation(options.margin, margin) if dilation is None else int(dilation)
    _finite(name, kind, result.values[result.mask])
    source = lightmap.dilation_source(result.mask, grow)
    values, grown = lightmap.dilate(result.values, result.mask, grow, source)
    values = np.where(grown[..., None] if values.ndim == 3 else grown, values, 0.0)
    seam_entries, seam_attrs = {}, {}
    if scene is not None:
        values, seam_entries, seam_attrs = seam_step(scene, group, layers, result.values, result.mask, values, grow,
                                                     result.estimated_error, KINDS[kind].value_range,
                                                     fix=options.seam_fix, source=source)
    alpha = result.mask.astype(np.float32)
    uv_name = layers.get(group[0].name)
    h, w = result.mask.shape
    areas = {o.name: uvchecks.chart_area(uvmod.triangles_uv(o, layers[o.name])) for o in group}
    covered = {o.name: float((uvchecks.coverage(uvmod.triangles_uv(o, layers[o.name]), w, h) & result.mask).mean())
               for o in group} if len(group) > 1 else {group[0].name: float(result.mask.mean())}
    attrs = _attributes(kind, result, options, uv_name)
    if digest:
        attrs[HASH_KEY] = digest
    layout = layout_digest(group, uv_name)
    if layout:
        attrs[UV_DIGEST_KEY] = json.dumps(layout, sort_keys=True)
    if KINDS[kind].layout:
        attrs["il:layout"] = KINDS[kind].layout
    attrs["il:coverage"] = float(result.mask.mean())
    attrs["il:chart_area"] = float(sum(areas.values()))
    attrs["il:min_coverage"] = MIN_COVERAGE_TEXT
    if overlap is not None:
        attrs["il:overlap"] = float(overlap[1])
    attrs["il:margin"] = margin
    attrs["il:dilation"] = grow
    attrs.update(seam_attrs)
    if seam_entries:
        attrs["il:seams"] = json.dumps(seam_entries)
    if len(group) > 1:
        attrs["il:objects"] = json.dumps({o.name: {"coverage": covered[o.name], "chart_area": areas[o.name]}
                                          | ({"overlap": float(overlap[0][o.name])} if overlap else {})
                                          for o in group})
    kept = {}
    for key, named in (per_object or {}).items():
        mine = {o.name: PER_OBJECT[key](named[o.name]) for o in group if o.name in (named or {})}
        if mine:
            kept[key] = mine
            attrs["il:" + key] = json.dumps(mine)
    path = map_file(out, stems, name, kind)
    exr.write_exr(path, KINDS[kind].exr_channels(np.flipud(values), np.flipud(alpha)), attrs)
    png = map_file(out, stems, name, kind, ".png")
    io_png.write_png(png, np.flipud(preview(kind, values, np.ones(values.shape[:2], bool))))  # the EXR as written
    res = (values.shape[1], values.shape[0])
    entries = {}
    for o in group:
        extra = {"preview": png, "uv_layer": uv_name, "coverage": covered[o.name],
                 "chart_area": areas[o.name], "margin": margin, "dilation": grow,
                 "denoised": bool(options.denoise and KINDS[kind].denoise)}
        if overlap is not None:
            extra["overlap"] = float(overlap[0][o.name])
        extra.update((key, named[o.name]) for key, named in kept.items() if o.name in named)
        if o.name in seam_entries:
            extra["seams"] = seam_entries[o.name]
        entries[o.name] = entry(path, res, result, extra)
    return entries


def _write_vertices(group, kind, result, out, options, digest, stems):
    """The vertex target's files: one vertex EXR per object, and its colour attribute set to the values."""
    entries = {}
    _finite(group[0].name, kind, result.values)
    for o in group:
        v = np.asarray(result.values[o.name], np.float32)
        row = v[None, :] if v.ndim == 1 else v[None, :, :]
        path = map_file(out, stems, o.name, kind, "_vertex.exr")
        attrs = _attributes(kind, result, options, None)
        if digest:
            attrs[HASH_KEY] = digest
        attrs["il:layout"] = "one texel per mesh vertex, in vertex order"
        exr.write_exr(path, KINDS[kind].exr_channels(row, np.ones(row.shape[:2], np.float32)), attrs)
        attr = o.data.color_attributes.get(KINDS[kind].attribute)
        if attr is not None:
            rgba = np.ones((len(v), 4), np.float32)
            rgba[:, :3] = v[:, None] if v.ndim == 1 else v
            attr.data.foreach_set("color", rgba.ravel())
        entries[o.name] = entry(path, (len(v), 1), result, {"attribute": KINDS[kind].attribute})
    return entries
