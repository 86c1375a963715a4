"""The light-map pipeline: validate, UVs, temporary materials (white at the baked point), Cycles bakes, files,
restore. This module runs the steps; each lives in its own: :mod:`.plan` (checks, sizes, files, shards),
:mod:`.inputs` and :mod:`.resume` (unchanged maps), :mod:`.materials`, :mod:`.passes` (samples and errors),
:mod:`.cycles` (one map's bake), :mod:`.batch` (many maps per call), :mod:`.write` (files), :mod:`.report`;
what differs between kinds of map is their record in :mod:`.kinds`."""
import contextlib
import dataclasses
import os
import time

import bpy

from ..blender.materials import shows_layers, user_material
from ..blender.progress import Progress
from ..blender.state import SavedState
from ..core import budget, errors
from ..core.errors import ILError, InputError
from ..core.io.files import remove_stale_temporaries
from ..core.memo import FIGURES
from ..core.result import JobResult
from . import batch as batching, cost, cycles, uv as uvmod, uvcache, uvchecks, write
from .inputs import input_hash, lighting_digest, scene_inputs
from .kinds import KINDS
from .materials import TemporaryMaterials
from .options import BakeOptions
from .plan import ATLAS, check_time, planned_samples, say_skipped, file_stems, plan, shard, speed, validate
from .report import REPORT, Tracker, merge_report, summary
from .resume import unchanged_maps


def bake_lightmaps(objects, maps, out, options=None, scene=None, on_step=None):
    """Bake ``maps`` ("ao", "irradiance"; None: ``options.maps``) of mesh ``objects`` into folder ``out``;
    return a :class:`core.result.JobResult` (reads as the report, ``path`` is bake_report.json).

    Writes ``<out>/<object>_<map>.exr`` (+ ``.png`` preview) per object (``atlas_<map>``
    with ``options.atlas``), or ``<object>_<map>_vertex.exr`` for the vertex target, and
    merges ``<out>/bake_report.json`` (a shard's part with ``options.shard``), which then holds every asked-for
    map on disk: maps unchanged under ``overwrite`` too (:func:`resume.unchanged_maps`), also when nothing is
    baked. The user's file comes back as it was (materials,
    images, UV layers, selection, active object, render settings), also on errors and
    interruptions; only the products (generated "Lightmap" UV layer, "IL AO" /
    "IL Irradiance" colour attributes) stay when ``options.keep_products``. The bakes light the scene through the
    user's own materials where the add-on's layers (light-map preview, shading model, environment mapping) show.
    ``on_step(message)`` is called at every step (progress hooks, tests).

    Report entry per object and map: DESIGN.md's "file", "resolution", "samples" (per texel, all bakes),
    "seconds" (the map's bakes, denoising and files) and "estimated_error" (RMS over covered texels,
    None when not estimated), plus "error_estimate" (which estimate that is, see passes.ESTIMATES),
    "cycles_seconds" (inside the Cycles bake calls), "pilot_samples" (target_error runs) and, for
    images, "preview", "uv_layer", "coverage", "denoised", "unwrap" (the unwrapper of a layout generated in this
    run: "smart_project" or "lightmap_pack", ending in "+raster_pack" when its charts were placed again by their
    texels), "low_fill" (the warning line of a generated layout covering under uvchecks.FILL of its map) and
    "uv_cache" ([key, index] of the layout in ``<out>/.il-uv-cache``: an export of a file without the layer reads it)
    and "unmapped" (the warning line of faces the layer gives no texel, :func:`uvchecks.check_unmapped`), and
    "inputs" (digests of what in the scene the map was baked from, :func:`inputs.scene_inputs`: an export names
    the objects changed since).
    """
    named = isinstance(out, (str, os.PathLike)) and os.fspath(out).strip()
    with FIGURES.stored(figures_folder(out)) if named else contextlib.nullcontext():
        return _bake(objects, maps, out, options, scene, on_step)


def figures_folder(out):
    """Where a bake into ``out`` keeps the figures of its meshes and layouts (:class:`core.memo.Store`) for reruns
    in other processes: beside the UV cache."""
    return os.path.join(os.path.abspath(os.fspath(out)), uvcache.DIR, "figures")


def _bake(objects, maps, out, options, scene, on_step):
    options = options or BakeOptions()
    scene = scene or bpy.context.scene
    with uvmod.fixed_geometry():        # meshes are read once: only UV layers change (and flipped normals, read again)
        return _bake_fixed(objects, maps, out, options, scene, on_step)


def _bake_fixed(objects, maps, out, options, scene, on_step):
    objects, maps, out, skipped, flips, failed = validate(scene, objects, maps, out, options)
    for folder in (out, os.path.join(out, uvcache.DIR), figures_folder(out)):
        remove_stale_temporaries(folder)       # what a killed earlier run was writing
    say_skipped(skipped)
    if options.denoise and options.target != "image":
        errors.warn("denoise ignored: the denoiser works on image maps, not on vertex colours")
    t_all = time.perf_counter()
    everyone = list(objects)                   # show their bake materials to the others' bakes, baked or not
    report_name = REPORT
    if options.shard:
        objects, report_name = shard(objects, options)
    groups = [(ATLAS, objects)] if (options.atlas and options.target == "image") else [(o.name, [o]) for o in objects]
    lighting = lighting_digest(scene)
    parts = {}
    digests = {(name, m): input_hash(scene, group, m, options, lighting, parts) for name, group in groups for m in maps}
    del parts
    stems = file_stems()
    report_path = os.path.join(out, report_name)
    unchanged, kept = {}, {}
    if options.overwrite and not options.force:
        unchanged, kept = unchanged_maps(groups, maps, digests, out, options, stems, report_path)
    requested = objects
    groups = [(name, group) for name, group in groups if len(unchanged.get(name, ())) < len(maps)]
    objects = [o for _, group in groups for o in group]
    steps = (1 if options.target == "image" and groups else 0) + sum(len(maps) - len(unchanged.get(n, ()))
                                                                        for n, _ in groups)
    report = {"objects": {}, "skipped": dict(skipped), "unchanged": unchanged, "failed": failed}
    if kept or not groups:                 # the report describes the unchanged maps too, also if nothing is baked
        merge_report(report_path, {"objects": kept, "seconds": time.perf_counter() - t_all, "skipped": dict(skipped),
                                    "unchanged": unchanged, "failed": failed})
    if not groups:
        report["seconds"] = time.perf_counter() - t_all
        return JobResult(report, report_path, summary(report))
    variants = cycles.render_variants(scene, everyone)
    saved = cycles.bake_settings(scene) + [(owner, attr) for owner, attr, _ in variants]
    layered = _layered(scene, everyone)
    with Progress("bake", steps) as progress, SavedState(scene, everyone + layered, saved) as state:
        run = _Run(scene, maps, out, options, report, report_path, digests, stems, t_all, progress, on_step, state,
                   TemporaryMaterials(state), world=scene.world)
        for o in layered:                   # the other objects light the bakes through the user's own materials
            for slot in o.material_slots:
                slot.material = user_material(slot.material)
        cycles.evaluate_as_render(scene, variants)
        cycles.show(everyone, state)
        shapes = {}
        run.inputs = {(name, m): {o.name: scene_inputs(scene, o, m, lighting, shapes) for o in group}
                      for name, group in groups for m in maps}
        cycles.flip_inside_out(scene, everyone, flips, state)
        cycles.setup_render(scene, options, state)
        if options.target == "image":
            run.step("light-map UVs")
            run.light_map_uvs(objects, groups, _sharing(requested, objects))
            scene.view_layers[0].update()      # the evaluated meshes carry the layers (also those from the cache)
        with uvmod.fixed_layouts(), run.merging():
            run.bake_all(groups, maps, everyone, unchanged)
        if run.errors and not report["objects"]:
            raise run.errors[0]
        if options.keep_products:       # products stay only when the whole bake succeeded (failed objects aside)
            state.keep |= {(o.data.name, uvmod.LIGHTMAP) for o in objects if o.name not in failed}
            generated = options.target == "image" and not options.uv_layer
            for o in objects if generated else ():      # a layer a preview added is the bake's now: Remove leaves it
                if o.name not in failed and o.data.get(uvmod.ADDED_BY_PREVIEW) == uvmod.LIGHTMAP:
                    del o.data[uvmod.ADDED_BY_PREVIEW]
            state.keep |= {(o.data.name, KINDS[m].attribute) for o in objects for m in maps if o.name not in failed}
        progress_line = run.tracker.final(report)
    report["seconds"] = time.perf_counter() - t_all
    if failed:
        merge_report(report_path, {"objects": {}, "seconds": report["seconds"], "failed": failed})
    return JobResult(report, report_path, summary(report) + progress_line)


def _layered(scene, everyone):
    """The objects of ``scene`` other than ``everyone`` whose slots show the add-on's material layers
    (``blender.materials.shows_layers``) and can take the user's own for the bakes: editable meshes (the others are
    named in a warning: the bakes see their layers)."""
    baked = {o.as_pointer() for o in everyone}
    layered = [o for o in scene.objects if o.as_pointer() not in baked and shows_layers(o)]
    fixed = [o for o in layered if o.type != "MESH" or o.library is not None or o.data.library is not None]
    if fixed:
        errors.warn("the bakes see the Illumination Lab materials shown on " + ", ".join(o.name for o in fixed)
                    + " (linked from a library, or not meshes: their own materials cannot be put back for the bake)")
    return [o for o in layered if o not in fixed]


def _sharing(requested, baked):
    """The objects of ``requested`` not in ``baked`` whose mesh a baked object shares (linked duplicates whose maps
    are unchanged), in ``requested`` order."""
    meshes = {o.data.as_pointer() for o in baked}
    names = {o.name for o in baked}
    return [o for o in requested if o.name not in names and o.data.as_pointer() in meshes]


#: Seconds between merges of finished maps into the report file while a run writes them. Each merge rewrites the
#: whole report, so a merge after every map made a level's run quadratic in its objects (207 objects: 3.8 s).
MERGE_EVERY = 1.0


@dataclasses.dataclass
class _Run:
    """One run of :func:`bake_lightmaps` inside its saved state: the light-map layers, the report so far
    (``report``; its maps not yet in ``report_path`` in ``unmerged``, see :meth:`merging`), failures
    ({name: reason} in ``report["failed"]``, the errors in ``errors``) and the progress line."""
    scene: object
    maps: list
    out: str
    options: BakeOptions
    report: dict
    report_path: str
    digests: dict
    stems: dict
    t_all: float
    progress: object
    on_step: object
    state: object
    temporary: TemporaryMaterials
    layers: dict = dataclasses.field(default_factory=dict)
    sides: dict = dataclasses.field(default_factory=dict)
    margins: dict = dataclasses.field(default_factory=dict)
    measured: set = dataclasses.field(default_factory=set)       # layouts whose margin was measured
    unwraps: dict = dataclasses.field(default_factory=dict)
    windows: dict = dataclasses.field(default_factory=dict)
    caches: dict = dataclasses.field(default_factory=dict)
    fills: dict = dataclasses.field(default_factory=dict)
    errors: list = dataclasses.field(default_factory=list)
    tracker: Tracker = None
    pace: cost.Speed = None
    uv_cache: uvcache.UVCache = None
    unmerged: dict = dataclasses.field(default_factory=dict)
    world: object = None              # the scene's own world (None: none; the bakes get a black one)
    inputs: dict = dataclasses.field(default_factory=dict)   # {(name, kind): {object: inputs.scene_inputs}}
    merged_at: float = float("-inf")

    def step(self, message):
        self.progress.step(message)
        if self.on_step:
            self.on_step(message)

    def fail(self, name, error):
        """Record a group's failure; the level goes on (the error itself is raised when nothing else is baked)."""
        self.report["failed"][name] = str(error)
        self.errors.append(error)
        errors.warn(f"'{name}' failed: {error}")

    def pending(self, target, kind):
        """Map ``kind`` of ``target`` is still to bake (not unchanged, not failed)."""
        return kind not in self.report["unchanged"].get(target.name, ()) and target.name not in self.report["failed"]

    def light_map_uvs(self, objects, groups, leaders=()):
        """The light-map UV layers of every group (one layout for the atlas); a group that fails is recorded.
        ``leaders``: objects not baked in this run (their maps unchanged) that share a mesh with a baked one; their
        layouts are settled first, so that the mesh keeps the layer their maps on disk were baked through."""
        self.uv_cache = uvcache.UVCache(os.path.join(self.out, uvcache.DIR))
        if not self.options.atlas:
            for o in leaders:
                try:
                    uvmod.prepare(self.scene, [o], self.state, self.options, cache=self.uv_cache)
                except (InputError, ILError):
                    pass                         # its own maps are on disk; the baked duplicate unwraps alone
        if self.options.atlas:
            self.record(uvmod.prepare(self.scene, objects, self.state, self.options, together=True,
                                      cache=self.uv_cache))
            return
        t0, todo = time.perf_counter(), sum(len(g) for _, g in groups)
        for i, (name, group) in enumerate(groups):
            if i:
                self.uv_progress(i, len(groups), time.perf_counter() - t0, todo)
            try:
                made = uvmod.prepare(self.scene, group, self.state, self.options, cache=self.uv_cache)
            except (InputError, ILError) as e:
                self.fail(name, e)
                continue
            self.record(made)

    def bake_all(self, groups, maps, everyone, unchanged):
        """Plan, check and bake every map of ``groups`` (their light-map layers in place)."""
        scene, options = self.scene, self.options
        targets = plan(scene, [(n, g) for n, g in groups if n not in self.report["failed"]], maps, self.layers,
                       self.sides, options, self.fail, self.windows)
        if not targets:
            raise self.errors[0]
        self.check_fill(targets)
        self.measure_margins(targets)
        if options.texel_density is not None and not options.sizes:
            check_time([t.size for t in targets if t.size], maps, options, "max resolution", speed(scene, options))
        batched, singles = batching.batches(scene, targets, self.layers, self.state, options, maps)
        self.tracker = Tracker(targets, maps, unchanged, options)
        self.pace = speed(scene, options)
        for m in maps:
            self.temporary.assign(everyone, m)      # every object shows the same materials to the others' bakes
            alone = []
            with cycles.world_for(scene, m):
                for batch in batched:
                    alone += self.bake_batch(batch, m)
                for target in alone + singles:
                    self.bake_alone(target, m)

    def record(self, made):
        """Keep a :class:`uv.Layouts`' layers, sides, margins, unwrappers, windows and UV cache keys."""
        for have, new in ((self.layers, made.layers), (self.sides, made.sides), (self.margins, made.margins),
                          (self.unwraps, made.unwraps), (self.windows, made.windows), (self.caches, made.caches)):
            have.update(new)

    def check_fill(self, targets):
        """uvchecks.low_fill of each generated layout at its map's final size (the plan may enlarge the side the layout
        was made for; its margin grows with it); the lines go to ``fills``."""
        for t in targets:
            first = t.group[0].name
            if t.size and first in self.sides:
                side = self.windows[first][2] if first in self.windows else t.size[0]
                margin = self.margins[first] * side / self.sides[first]
                line = uvchecks.low_fill(t.group, t.size, margin, self.options)
                if line:
                    self.fills.update((o.name, line) for o in t.group)

    def measure_margins(self, targets):
        """The margin of each image map's layout the bake did not make (no side: a reused "Lightmap" layer, the
        ``--uv-layer``): measured at the map's size (:func:`uvchecks.layout_margin`) for the report, with a warning
        below the asked one; 0 without it where faces share texels (the overlap check has said so). The map is still
        dilated by the asked margin (nearest covered texel: no texel takes another chart's value while it is nearer
        its own)."""
        asked = float(self.options.margin)
        for t in targets:
            first = t.group[0].name
            if not t.size or first in self.sides or self.options.target != "image":
                continue
            shared = t.overlap is not None and t.overlap[1] > uvchecks.MAX_OVERLAP      # charts share texels
            margin = 0.0 if shared else uvchecks.layout_margin(t.group, self.layers, t.size, asked)
            self.margins[first] = margin
            self.measured.add(first)
            if margin < asked and not shared:
                layer = self.layers[first]
                fix = ("bake without a UV layer of your own to have one made with the margin" if self.options.uv_layer
                       else "remove the layer to have one made with the margin")
                errors.warn(f"'{t.name}': light-map layer '{layer}' keeps a margin of {margin:g} texel(s) between its "
                            f"charts at {t.size[0]}x{t.size[1]}, below the asked {asked:g} (filtered and mipmapped "
                            f"reads mix charts); {fix}")

    def uv_progress(self, done, total, seconds, objects):
        """A progress line of the UV step on stderr in batch: groups done, elapsed, ETA (seconds per group so far)."""
        eta = seconds / done * (total - done)
        message = f"light-map UVs: {done}/{total} ({objects} objects), elapsed {seconds:.1f} s, ETA {eta:.0f} s"
        self.progress.note(message, done / total)

    def bake_batch(self, batch, kind):
        """Bake and write map ``kind`` of the pending targets of ``batch`` in shared Cycles calls; return the
        targets to bake alone when the shared call fails (one of them breaks it)."""
        batch = [t for t in batch if self.pending(t, kind)]
        if not batch:
            return []
        try:
            results = batching.bake_batch(self.scene, batch, kind, self.options, self.layers, self.temporary,
                                          self.state)
        except ILError:
            return batch
        for target in batch:
            self.announce(target, kind)
            try:
                self.finish(target, kind, results.pop(target.name), time.perf_counter())
            except (InputError, ILError) as e:
                self.fail(target.name, e)
        return []

    def bake_alone(self, target, kind):
        """Bake and write map ``kind`` of ``target`` by its own Cycles calls, if pending."""
        if not self.pending(target, kind):
            return
        self.announce(target, kind)
        t_map = time.perf_counter()
        try:
            result = cycles.bake_map(self.scene, target.group, kind, self.options, self.layers, target.size,
                                     self.temporary.assign(target.group, kind), self.state)
            result.seconds = 0.0
            self.finish(target, kind, result, t_map)
        except (InputError, ILError) as e:
            self.fail(target.name, e)

    def announce(self, target, kind):
        """The progress step of a map: its size, peak memory and seconds by the cost model, the level's tracker."""
        size, estimate = target.size, ""
        if size:
            peak = cost.peak_bytes(size[0], size[1], [kind], self.options.denoise)
            seconds = cost.seconds(size[0], size[1], [kind], planned_samples(self.options), self.pace)
            estimate = f" {size[0]}x{size[1]} (about {budget.format_bytes(peak)}, {seconds:.2g} s)"
        self.step(f"{target.name}: {kind}" + (estimate or " (vertices)") + self.tracker.line())
        self.tracker.done(target.name, kind)

    def finish(self, target, kind, result, t_map):
        """Check and write a baked map and put its entries in the report; they are merged into the report file at
        once when the last merge is MERGE_EVERY seconds old, else with the next one."""
        name, group = target.name, target.group
        if target.size is not None:
            write.check_covered(name, group, kind, result, self.layers, target.areas)
        write.check_plausible(self.scene, name, group, kind, result)
        write.check_lit(self.scene, name, kind, result, self.world)
        margin = self.margins.get(group[0].name, float(self.options.margin))
        t_files = time.perf_counter()
        result.seconds += t_files - t_map
        per_object = {"low_fill": self.fills, "unwrap": self.unwraps, "uv_cache": self.caches,
                      "unmapped": target.unmapped, "inputs": self.inputs.get((name, kind))}
        grow = int(self.options.margin) if group[0].name in self.measured else None
        entries = write.write_map(name, group, kind, result, self.out, self.options, self.layers, margin,
                                  target.overlap, self.digests[(name, kind)], self.stems, self.scene, per_object,
                                  dilation=grow)
        for o in group:
            entries[o.name]["seconds"] = round(result.seconds + time.perf_counter() - t_files, 4)  # files included
            self.report["objects"].setdefault(o.name, {})[kind] = entries[o.name]
            self.unmerged.setdefault(o.name, {})[kind] = entries[o.name]
        if time.perf_counter() - self.merged_at >= MERGE_EVERY:
            self.merge()

    @contextlib.contextmanager
    def merging(self):
        """Merge the maps still unmerged when the bakes end, also when they stop on an error (a full disk, Ctrl-C:
        finished maps are in the report; a merge that fails then is dropped, the error raised is the first)."""
        try:
            yield
        except BaseException:
            with contextlib.suppress(Exception):
                self.merge()
            raise
        self.merge()

    def merge(self):
        """Merge the unmerged maps and the failures into the report file (the maps stay unmerged if it fails, for
        the merge :meth:`merging` makes when the run stops); then the UV cache and the figures are written (after
        a map is: a run that writes nothing leaves no cache)."""
        if not self.unmerged:
            return
        part = {"objects": self.unmerged, "skipped": self.report["skipped"], "unchanged": self.report["unchanged"],
                "failed": self.report["failed"], "seconds": time.perf_counter() - self.t_all}
        merge_report(self.report_path, part)
        self.unmerged, self.merged_at = {}, time.perf_counter()
        if self.uv_cache:
            self.uv_cache.flush()
        if FIGURES.store is not None:
            FIGURES.store.flush()
