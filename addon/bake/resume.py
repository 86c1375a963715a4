"""Resume: the maps on disk whose inputs are unchanged (their header's input hash) and their report entries."""
import functools
import json
import math
import os

import numpy as np

from ..core.io import exr, png as io_png
from . import report as reports, uv as uvmod, write
from .inputs import HASH_KEY, UV_DIGEST_KEY, group_map_file, header_text, layout_digest, stored_header, stored_map
from .kinds import KINDS
from .passes import BakeResult
from .plan import map_file


def unchanged_maps(groups, maps, digests, out, options, stems, report_path):
    """({name: [kinds]} of the maps of ``groups`` [(name, objects)] whose file holds the input hash ``digests``
    {(name, kind): hash}, {object: {kind: report entry}} of them (:func:`_kept_entries`, old entries from
    ``report_path`` and the folder's bake_report.json)."""
    unchanged, kept = {}, {}
    old_reports = [reports.read_objects(report_path),
                   reports.read_objects(os.path.join(out, reports.REPORT))]
    for name, group in groups:
        for m in maps:
            path = group_map_file(name, m, out, options, group, stems)
            header = stored_header(path)      # a map baked from other inputs is not read further
            if header is None or header_text(header.get(HASH_KEY)) != digests[(name, m)]:
                continue
            stored = stored_map(path)         # the whole file reads (a damaged one is baked again)
            if (stored is not None and header_text(stored[0].get(HASH_KEY)) == digests[(name, m)]
                    and _on_its_layout(group, stored[0])):
                unchanged.setdefault(name, []).append(m)
                for o, e in _kept_entries(name, group, m, out, options, stems, stored, old_reports).items():
                    kept.setdefault(o, {})[m] = e
    return unchanged, kept


def _on_its_layout(group, header):
    """Whether a map still lies on a layout its group gets again: for each object, the layer the map was baked
    through (the header's il:uv_layer) holds the UVs it held (UV_DIGEST_KEY, by object), or the UV cache makes its
    layout again (il:uv_cache names it: the layer is the bake's product, written back from the cache by the next
    bake that needs it and read from the cache by an export). So a layer reused (no cache entry) and since edited or
    removed is baked through again; the input hash leaves that layer out, so that a rerun without it agrees with the
    first bake. A map without the digest (a vertex map, or written before it was kept) passes."""
    text = header_text(header.get(UV_DIGEST_KEY))
    if not text:
        return True
    try:
        stored = json.loads(text)
        cached = json.loads(header_text(header.get("il:uv_cache")) or "{}")
    except ValueError:
        return False
    if not isinstance(stored, dict) or not isinstance(cached, dict):
        return False
    rest = [o for o in group if not cached.get(o.name)]         # the cache makes the others' layouts again
    now = layout_digest(rest, header_text(header.get("il:uv_layer")))
    return all(now.get(o.name) == stored.get(o.name) for o in rest)


def _kept_entries(name, group, kind, out, options, stems, stored, old_reports):
    """``{object: report entry}`` of an unchanged map on disk (``stored``: :func:`stored_map` of its file): the entry
    of the first of ``old_reports`` ("objects" of reports) that agrees with the file (name, resolution, samples,
    estimated error and its kind, UV layer), else one rebuilt from the header's il:* attributes ("seconds" and
    "cycles_seconds" 0, as the file holds no timings; figures a file written before they were kept lacks are 0, the
    margin the option's). Writes the PNG preview of an image map when it is missing."""
    header, res = stored
    number = functools.partial(_number, header)
    path = group_map_file(name, kind, out, options, group, stems)
    result = BakeResult(None, None, int(number("il:samples")), 0.0,
                        number("il:estimated_error", float("nan")), header_text(header.get("il:error_estimate")) or "",
                        int(number("il:pilot_samples")), 0.0,
                        unlit=header_text(header.get("il:unlit")) or "")
    extras, png = {group[0].name: {"attribute": KINDS[kind].attribute}}, None
    if options.target == "image":
        png = map_file(out, stems, name, kind, ".png")
        if not os.path.exists(png):
            channels, _ = exr.read_exr(path)
            values = KINDS[kind].from_exr(channels)
            io_png.write_png(png, write.preview(kind, values, np.ones(values.shape[:2], bool)))
        try:
            per = json.loads(header_text(header.get("il:objects")) or "{}")
            seams = json.loads(header_text(header.get("il:seams")) or "{}")
            kept = {key: json.loads(header_text(header.get("il:" + key)) or "{}") for key in write.PER_OBJECT}
        except ValueError:
            per, seams, kept = {}, {}, {}
        whole = {"coverage": number("il:coverage"), "chart_area": number("il:chart_area")}
        if header.get("il:overlap") is not None:
            whole["overlap"] = number("il:overlap")
        extras = {}
        for o in group:
            own = per.get(o.name) if isinstance(per, dict) and isinstance(per.get(o.name), dict) else whole
            extras[o.name] = {"preview": png, "uv_layer": header_text(header.get("il:uv_layer")) or None,
                              "coverage": own.get("coverage"), "chart_area": own.get("chart_area"),
                              "margin": uvmod.margin_value(number("il:margin", float(options.margin))),
                              "dilation": int(number("il:dilation", uvmod.dilation(
                                  options.margin, number("il:margin", float(options.margin))))),
                              "denoised": header_text(header.get("il:denoised")) == "1"}
            if "overlap" in own:
                extras[o.name]["overlap"] = own["overlap"]
            if isinstance(seams, dict) and isinstance(seams.get(o.name), dict):
                extras[o.name]["seams"] = seams[o.name]
            for key, values in kept.items():
                if isinstance(values, dict) and isinstance(values.get(o.name), write.PER_OBJECT[key]):
                    extras[o.name][key] = values[o.name]
    entries = {}
    for o in group:
        fresh = write.entry(path, res, result, extras[o.name])
        old = next((r[o.name][kind] for r in old_reports if kind in r.get(o.name, {})), None)
        if old is not None and _agrees(old, fresh):
            fresh = dict(old, file=path, **({"preview": png} if png else {}))
        entries[o.name] = fresh
    return entries


def _agrees(old, new):
    """Whether report entry ``old`` describes the same map file as ``new`` (rebuilt from its header)."""
    try:
        same_error = (old.get("estimated_error") is None) == (new["estimated_error"] is None) and (
            new["estimated_error"] is None
            or math.isclose(float(old["estimated_error"]), new["estimated_error"], rel_tol=1e-6))
        return (os.path.basename(str(old.get("file"))) == os.path.basename(new["file"])
                and list(old.get("resolution", ())) == new["resolution"] and old.get("samples") == new["samples"]
                and old.get("error_estimate") == new["error_estimate"] and old.get("uv_layer") == new.get("uv_layer")
                and same_error)
    except (TypeError, ValueError):
        return False


def _number(header, key, default=0.0):
    """The header's attribute ``key`` as a float, ``default`` when missing or not a number."""
    try:
        return float(header_text(header.get(key)))
    except (TypeError, ValueError):
        return default
