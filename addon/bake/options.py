"""Bake options: the one declaration the operator, its panel, scripts/bake.py and other tools build from."""
import dataclasses

from ..core.errors import InputError
from ..core.io.files import check_output_dir as check_out_dir  # noqa: F401  (one home: core.io.files)
from ..core.lightmap import MAX_RESOLUTION, SMALLEST_TARGET_ERROR
from ..core.options import Options, option
from .kinds import KINDS

MAP_CHOICES = tuple((k.id, k.label, k.description) for k in KINDS.values())
MAPS = tuple(KINDS)
TARGET_CHOICES = (("image", "Image", "EXR map + PNG preview per object"),
                  ("vertex", "Vertex Colors", "A colour attribute per map"))
TARGETS = tuple(t[0] for t in TARGET_CHOICES)


@dataclasses.dataclass
class BakeOptions(Options):
    """Everything a bake needs besides the objects and the output folder (see each field's help).

    The side of a map is ``resolution`` unless ``texel_density`` is set: then T √(area / UV coverage),
    capped at ``max_resolution``. With ``target_error`` the samples come from a pilot pair of bakes
    (passes.bake_to_error) of ``pilot_samples``, at most ``max_samples``. ``sizes`` is
    {object name: (width, height)} overriding the side for that object (a UV layout made for a given
    image size, e.g. a radiosity patch atlas; image target without atlas only).
    """
    maps: list = option(["ao"], "Maps", "maps to bake", kind=str, choices=MAP_CHOICES, multiple=True,
                        item="map")
    resolution: int = option(256, "Resolution", "map side in texels (the machine's memory may allow less, see "
                             "README)", minimum=1, maximum=MAX_RESOLUTION, group="size", subtype="PIXEL")
    texel_density: float = option(None, "Texels/m", "texels per metre of surface (side capped)", kind=float,
                                  above=0, soft_max=1024.0, metavar="T", group="size", ui_default=32.0)
    max_resolution: int = option(4096, "Max Resolution", "cap of the side chosen from the texel density",
                                 minimum=1, maximum=MAX_RESOLUTION, subtype="PIXEL")
    samples: int = option(64, "Samples", "Cycles samples", minimum=1, maximum=1 << 20, group="quality")
    target_error: float = option(None, "Target Error", "RMS Monte Carlo error wanted (k_A units for AO, W/m² "
                                 "for irradiance); samples chosen from a pilot bake's variance", kind=float,
                                 above=0, metavar="E", group="quality", ui_default=0.01)
    pilot_samples: int = option(8, "Pilot Samples", "samples per texel of the pilot pair of bakes", minimum=2,
                                cli=False, ui=False)
    max_samples: int = option(4096, "Max Samples", "most samples (pilots included) a target error may spend",
                              minimum=2, cli=False, ui=False)
    ao_distance: float = option(10.0, "AO Distance", "AO ray length in m (World > Light Settings > Distance)",
                                above=0, metavar="D", unit="LENGTH")
    bounces: int = option(3, "Bounces", "diffuse bounces of the irradiance bake (0 = direct light only)",
                          minimum=0, maximum=1024, metavar="K")
    margin: int = option(4, "Margin", "dilation beyond the covered texels, in texels", minimum=0, maximum=1024,
                         metavar="PX", subtype="PIXEL")
    denoise: bool = option(False, "Denoise", "Blender's denoiser (OpenImageDenoise) on the image maps")
    seam_fix: bool = option(True, "Fix Seams", "stitch the texels along chart seams where the jump across them is "
                            "above the bake's noise (the seams are measured either way)", flag="--no-seam-fix")
    uv_layer: str = option(None, "UV Layer", "existing UV layer used as it is (default: generate 'Lightmap')",
                           kind=str, metavar="NAME")
    target: str = option("image", "Target", "image maps or vertex colours", choices=TARGET_CHOICES)
    atlas: bool = option(False, "Shared Atlas", "one shared map for all objects")
    seed: int = option(0, "Seed", "Cycles seed of the (first) bake", minimum=0, maximum=2 ** 31 - 1, ui=False)
    overwrite: bool = option(False, "Overwrite", "replace existing output files; maps whose inputs are unchanged "
                             "(the hash in their EXR header) are skipped: rerun an interrupted bake with it to resume")
    force: bool = option(False, "Force", "bake every map again, also those whose inputs are unchanged (implies "
                         "Overwrite)")
    keep_products: bool = option(True, "Keep Products", "leave the generated 'Lightmap' UV layer / vertex "
                                 "colour attributes on the meshes", cli=False, ui=False)
    shard: str = option(None, "Shard", "bake only share K of N (K/N, 1-based) of the objects, balanced by texels; "
                        "its report part is bake_report.shard-K-of-N.json (join the parts with --merge)", kind=str,
                        metavar="K/N", ui=False)
    batch: bool = option(True, "Batch", "bake the maps of many objects in one Cycles call (one scene sync) where "
                         "the result is the same", cli=False, ui=False)
    sizes: dict = None

    def check(self):
        if self.shard:
            shard_of(self.shard)
        if self.force:
            self.overwrite = True
        if self.texel_density is None:
            self.resolution = int(self.resolution)
        if int(self.max_samples) < int(self.pilot_samples):
            raise InputError(f"pilot samples must be at least 2 and maximum samples at least the pilot samples, "
                             f"got {self.pilot_samples} and {self.max_samples}")
        self.check_target(())
        self.uv_layer = self.uv_layer or None
        if self.sizes:
            if self.target != "image" or self.atlas:
                raise InputError("per-object map sizes need the image target without a shared atlas")
            for name, (w, h) in self.sizes.items():
                if not (1 <= int(w) <= MAX_RESOLUTION and 1 <= int(h) <= MAX_RESOLUTION):
                    raise InputError(f"map size of '{name}' must be between 1 and {MAX_RESOLUTION}, got {w}x{h}")

    def check_target(self, maps):
        """Refuse a ``target_error`` below the float32 maps' resolution, or one that one of ``maps`` cannot reach
        within ``max_samples``, before any bake, naming the smallest that can (each kind's
        ``smallest_target_error``, :mod:`.kinds`)."""
        if self.target_error is None:
            return
        target = float(self.target_error)
        limits = [(SMALLEST_TARGET_ERROR, "in float32 maps")]
        limits += [(KINDS[m].smallest_target_error(self.max_samples),
                    KINDS[m].target_limit.format(max_samples=int(self.max_samples))) for m in maps]
        for least, why in limits:
            if not target >= least:
                raise InputError(f"target error {target:g} cannot be reached {why}: the smallest target error is "
                                 f"{least:.3g}")


def shard_of(text):
    """(K, N) of a shard "K/N" with 1 <= K <= N; InputError otherwise."""
    try:
        k, n = (int(x) for x in str(text).split("/"))
    except ValueError:
        raise InputError(f"shard must be K/N (e.g. 2/8), got {text!r}") from None
    if not 1 <= k <= n:
        raise InputError(f"shard K/N needs 1 <= K <= N, got {text}")
    return k, n


def article(word):
    """``word`` with its indefinite article, as it is read: 'an empty', 'a curve', 'an 8x8', 'an 11x11', 'a 16x16'.
    Numbers by their leading group of three digits (eight, eleven, eighteen, eighty… and eight hundred… are
    read with a vowel first)."""
    text = str(word)
    head = text.split("x")[0]
    if head.isdigit():
        lead = head[:len(head) % 3 or 3]
        vowel = lead.startswith("8") or lead in ("11", "18")
    else:
        vowel = text[:1].lower() in "aeiou"
    return ("an " if vowel else "a ") + text


def validate_maps(maps):
    maps = [m.lower() for m in maps]
    if not maps:
        raise InputError(f"no maps asked for: choose {', '.join(MAPS[:-1])} and/or {MAPS[-1]}")
    for m in maps:
        if m not in MAPS:
            raise InputError(f"unknown map {m!r}: choose from {', '.join(MAPS)}")
    return list(dict.fromkeys(maps))
