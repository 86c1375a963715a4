"""The kinds of light map, one record each: what options, cost, the bakes and the files read about a kind.

Adding a kind is one :class:`Kind` in KINDS, its temporary-material builder in :mod:`.materials` and its tests.
No bpy here: the material builder is named, and its numpy estimator lives in :mod:`core.lightmap`.
"""
import dataclasses
import math
from typing import Callable, Optional

import numpy as np

from ..core import directional, lightmap
from ..core.io import png as io_png


@dataclasses.dataclass(frozen=True)
class Bake:
    """One Cycles call of a kind baked in several (``Kind.bakes``): its type and pass filter, the reading of its
    RGBA (value = RGB × scale + offset), and what its material shows: ``tilt`` t (a white Lambert of normal
    normalize(N + t - (t·N) N)) and ``normal`` (1: an emission of that normal × 0.5 + 0.5, for an EMIT bake)."""
    bake_type: str
    pass_filter: Optional[frozenset]
    scale: float
    offset: float
    tilt: tuple
    normal: int

    def read(self, rgba):
        return rgba[..., :3] * self.scale + self.offset


def tilted_bakes(tilts):
    """The bakes of a directional map: per tilt t_k, E(n_k) (DIFFUSE direct + indirect, × π) and n_k (EMIT)."""
    out = []
    for t in tilts:
        out += [Bake("DIFFUSE", frozenset({"DIRECT", "INDIRECT"}), math.pi, 0.0, t, 0),
                Bake("EMIT", None, 2.0, -1.0, t, 1)]
    return tuple(out)


@dataclasses.dataclass(frozen=True)
class Kind:
    """One kind of light map.

    id, label, description  the option choice (``BakeOptions.maps``)
    bake_type, pass_filter  Cycles ``object.bake`` type and pass filter (None: none; "INDIRECT" is dropped
                            at 0 bounces)
    bounces                 follows ``options.bounces`` (Cycles' diffuse bounces, EXR il:bounces); else 0 bounces
    lit                     lights, world and materials shade it: they are in its input hash (DESIGN.md resume)
    channels, scale         EXR channels ("Y", "RGB" or a tuple of names) and the factor from Cycles' value
                            (E = π × DIFFUSE)
    quantity, units         EXR il:quantity, il:units
    attribute               the vertex target's colour attribute
    value_range             (low, high or None) the quantity lives in; the denoised map is clipped to it
    bytes_per_texel         peak bytes per texel of one map (bake/cost.py)
    seconds_per_texel_sample  Cycles CPU seconds per texel and sample in a plain scene (bake/cost.py)
    halves                  a fixed-sample bake is two independent halves, its error measured from their difference
    variance                per-sample variance of a single bake, (values, mask) -> σ² (None: not estimated)
    estimate                the ESTIMATES key of that single-bake error ("binomial", "none")
    smallest_target_error   (max_samples) -> the smallest target error it may ask for
    target_limit            why a smaller target error is refused ({max_samples} filled in)
    preview                 PNG display mapping of the values (core.io.png)
    material                name of its temporary-material builder in :mod:`.materials`
    per_material            one temporary material per original slot material (else one shared by every slot)
    zero_means_inside       a map 0 everywhere on an object whose faces look into itself is refused
    scale_option            (what, option) the length whose scale its shading has (vertex-target coarseness), or None
    bakes                   the Cycles calls of one bake when there are several (:class:`Bake`; empty: one call of
                            bake_type), their values combined by ``combine([values of each call]) -> values``
    layout                  EXR il:layout (how the channels are read), or ""
    denoise                 the denoiser applies (False: ``--denoise`` leaves the map as baked, with a warning)
    images_only             no vertex target (its values do not fit a colour attribute)
    """
    id: str
    label: str
    description: str
    bake_type: str
    pass_filter: Optional[frozenset]
    bounces: bool
    lit: bool
    channels: object
    scale: float
    quantity: str
    units: str
    attribute: str
    value_range: tuple
    bytes_per_texel: int
    seconds_per_texel_sample: float
    halves: bool
    variance: Optional[Callable]
    estimate: str
    smallest_target_error: Callable
    target_limit: str
    preview: Callable
    material: str
    per_material: bool
    zero_means_inside: bool = False
    scale_option: Optional[tuple] = None
    bakes: tuple = ()
    combine: Optional[Callable] = None
    layout: str = ""
    denoise: bool = True
    images_only: bool = False

    def read(self, rgba):
        """The map's values from Cycles' (..., 4) colours: the first channel (Y) or RGB × scale."""
        if len(self.channels) == 1:
            return rgba[..., 0].copy()
        return rgba[..., :len(self.channels)] * self.scale

    def exr_channels(self, values, alpha):
        """{EXR channel: array} of ``values`` (..., C) with ``alpha``."""
        if len(self.channels) == 1:
            return {self.channels: values, "A": alpha}
        return {c: values[..., i] for i, c in enumerate(self.channels)} | {"A": alpha}

    def from_exr(self, channels):
        """The values of a map read back from its EXR channels."""
        if len(self.channels) == 1:
            return channels[self.channels]
        return np.stack([channels[c] for c in self.channels], axis=-1)

    def cycles_bounces(self, options):
        """(diffuse bounces, max bounces) of its Cycles bakes."""
        if not self.bounces:
            return 0, 0
        return int(options.bounces), max(int(options.bounces), 1)

    def cycles_pass_filter(self, options, bake=None):
        """The ``pass_filter`` of its Cycles bakes (of ``bake``, one of ``bakes``), or None."""
        wanted = self.pass_filter if bake is None else bake.pass_filter
        if wanted is None:
            return None
        return set(wanted) if options.bounces > 0 else set(wanted) - {"INDIRECT"}


KINDS = {k.id: k for k in (
    Kind(id="ao", label="Ambient Occlusion", description="k_A (1 = open)",
         bake_type="AO", pass_filter=None, bounces=False, lit=False,
         channels="Y", scale=1.0, quantity="ambient occlusion k_A (1 = open)", units="1", attribute="IL AO",
         value_range=(0.0, 1.0), bytes_per_texel=240, seconds_per_texel_sample=9e-7,
         halves=False, variance=lightmap.per_sample_variance_ao, estimate="binomial",
         smallest_target_error=lightmap.smallest_target_error_binary,
         target_limit="for ao within {max_samples} samples", preview=io_png.srgb_encode,
         material="ao_material", per_material=False, zero_means_inside=True,
         scale_option=("the AO distance", "ao_distance")),
    Kind(id="irradiance", label="Irradiance", description="E in W/m² (RGB)",
         bake_type="DIFFUSE", pass_filter=frozenset({"DIRECT", "INDIRECT"}), bounces=True, lit=True,
         channels="RGB", scale=math.pi, quantity="irradiance E", units="W/m^2", attribute="IL Irradiance",
         value_range=(0.0, None), bytes_per_texel=300, seconds_per_texel_sample=1.6e-6,
         halves=True, variance=None, estimate="none",
         smallest_target_error=lightmap.smallest_target_error_unbounded,
         target_limit="in float32 maps", preview=io_png.tonemap,
         material="irradiance_material", per_material=True),
    Kind(id="directional", label="Directional (L1 SH)",
         description="L1 spherical-harmonic irradiance that follows normal maps (12 channels, Godot's order)",
         bake_type="DIFFUSE", pass_filter=frozenset({"DIRECT", "INDIRECT"}), bounces=True, lit=True,
         channels=directional.CHANNELS, scale=math.pi,
         quantity="L1 SH coefficients (Ramamoorthi & Hanrahan's convention) of a fit of E(n) near the surface "
         "normal, |b| <= 4a, E(n) = 0.886227 L00 + 1.023328 (L1-1 n_y + L10 n_z + L11 n_x), world space (Blender, Z up)",
         units="W/(m^2 sr)", attribute="IL Directional", value_range=(None, None),
         bytes_per_texel=1000, seconds_per_texel_sample=9.0e-6,
         halves=True, variance=None, estimate="none",
         smallest_target_error=lightmap.smallest_target_error_unbounded,
         target_limit="in float32 maps", preview=lambda v: io_png.tonemap(directional.ambient(v)),
         material="directional_material", per_material=True,
         bakes=tilted_bakes(directional.tilt_vectors()), combine=directional.combine,
         layout="L00.RGB, L1-1.RGB (n_y), L10.RGB (n_z), L11.RGB (n_x) in W/(m^2 sr), Godot's order; E(n) = "
                "0.886227 L00 + 1.023328 (L1-1 n_y + L10 n_z + L11 n_x) in W/m^2 for a world-space unit normal n; "
                "least-squares fit of 5 DIFFUSE bakes at the mesh normal and 4 tilts (docs/lightmaps.md)",
         denoise=False, images_only=True),
)}
"""{id: Kind} in the order the options offer them."""
