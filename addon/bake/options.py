"""Bake options: one dataclass shared by the operator, scripts/bake.py and other tools."""
import dataclasses

from ..core.errors import InputError
from ..core.io.files import check_output_dir as check_out_dir  # noqa: F401  (one home: core.io.files)
from ..core.lightmap import MAX_RESOLUTION

MAPS = ("ao", "irradiance")
TARGETS = ("image", "vertex")


@dataclasses.dataclass
class BakeOptions:
    """Everything a bake needs besides the objects, the maps and the output folder.

    resolution      square map side in texels (ignored when texel_density is set)
    texel_density   texels per metre; the side is then T √(area / UV coverage), capped
    max_resolution  the cap for texel_density
    samples         Cycles samples (ignored when target_error is set)
    target_error    wanted RMS Monte Carlo error over the covered texels (k_A units for AO, W/m² for
                    irradiance); the samples then come from pilot bakes (pipeline._bake_to_error)
    pilot_samples   samples per texel of the pilot pair of bakes (half each)
    max_samples     upper bound of the samples (pilots included) target_error may spend
    ao_distance     AO ray length in metres (World > Light Settings > Distance)
    bounces         diffuse bounces of the irradiance bake (0 = direct light only)
    margin          dilation in texels beyond the covered texels
    denoise         run Blender's denoiser (OpenImageDenoise, compositor) on image maps
    uv_layer        an existing UV layer used as it is; None generates "Lightmap"
    target          "image" (EXR + PNG per map) or "vertex" (a colour attribute per map)
    atlas           bake every object into one shared map ("atlas_<map>.exr")
    overwrite       replace existing output files
    keep_products   leave the generated "Lightmap" UV layer / vertex colour attributes on the meshes
    seed            Cycles seed of the (first) bake
    sizes           {object name: (width, height)} of its image map, overriding resolution and
                    texel_density for that object (a UV layout made for a given image size, e.g. a
                    radiosity patch atlas); image target without atlas only
    """
    resolution: int = 256
    texel_density: float = None
    max_resolution: int = 4096
    samples: int = 64
    target_error: float = None
    pilot_samples: int = 8
    max_samples: int = 4096
    ao_distance: float = 10.0
    bounces: int = 3
    margin: int = 4
    denoise: bool = False
    uv_layer: str = None
    target: str = "image"
    atlas: bool = False
    overwrite: bool = False
    keep_products: bool = True
    seed: int = 0
    sizes: dict = None

    def validate(self):
        """Raise InputError for any value out of range (before anything is touched)."""
        if self.texel_density is None:
            if not 1 <= int(self.resolution) <= MAX_RESOLUTION:
                raise InputError(f"resolution must be between 1 and {MAX_RESOLUTION}, got {self.resolution}")
        elif not self.texel_density > 0:
            raise InputError(f"texel density must be positive, got {self.texel_density}")
        if not 1 <= int(self.max_resolution) <= MAX_RESOLUTION:
            raise InputError(f"maximum resolution must be between 1 and {MAX_RESOLUTION}, got {self.max_resolution}")
        if self.target_error is None:
            if int(self.samples) < 1:
                raise InputError(f"samples must be at least 1, got {self.samples}")
        elif not self.target_error > 0:
            raise InputError(f"target error must be positive, got {self.target_error}")
        if int(self.pilot_samples) < 2 or int(self.max_samples) < int(self.pilot_samples):
            raise InputError(f"pilot samples must be at least 2 and maximum samples at least the pilot samples, "
                             f"got {self.pilot_samples} and {self.max_samples}")
        if not self.ao_distance > 0:
            raise InputError(f"AO distance must be positive, got {self.ao_distance}")
        if not 0 <= int(self.bounces) <= 1024:
            raise InputError(f"bounces must be between 0 and 1024, got {self.bounces}")
        if not 0 <= int(self.margin) <= 1024:
            raise InputError(f"margin must be between 0 and 1024 texels, got {self.margin}")
        if self.target not in TARGETS:
            raise InputError(f"target must be one of {', '.join(TARGETS)}, got {self.target!r}")
        if self.sizes:
            if self.target != "image" or self.atlas:
                raise InputError("per-object map sizes need the image target without a shared atlas")
            for name, (w, h) in self.sizes.items():
                if not (1 <= int(w) <= MAX_RESOLUTION and 1 <= int(h) <= MAX_RESOLUTION):
                    raise InputError(f"map size of '{name}' must be between 1 and {MAX_RESOLUTION}, got {w}x{h}")
        return self


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
        raise InputError("no maps asked for: choose ao and/or irradiance")
    for m in maps:
        if m not in MAPS:
            raise InputError(f"unknown map {m!r}: choose from {', '.join(MAPS)}")
    return list(dict.fromkeys(maps))
