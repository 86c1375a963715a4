"""Cost of a light-map bake before it starts: peak memory per map side, rough seconds, the largest side
that fits the machine (no bpy; the memory available comes from ``core.budget``).

Maps are baked one after the other, so the peak is that of the largest map: Blender's float RGBA
image, its pixels read back, the two half bakes and their combination (irradiance), the mask, the
dilation's index arrays, the flipped EXR channels and the PNG preview. BYTES_PER_TEXEL is the
measured peak RSS growth of a bake divided by its texels (scripts/bake.py, 2048² and 1024²,
``getrusage`` max RSS minus the RSS before the bake), with a margin.
"""
import os

from ..core import budget
from .kinds import KINDS
from .options import article

BYTES_PER_TEXEL = {k.id: k.bytes_per_texel for k in KINDS.values()}
"""Peak bytes per texel of one map (each kind's ``bytes_per_texel``): measured peak RSS growth over a 16² bake,
bpy 5.0.1, 1024² and 2048²: AO 181-185, irradiance 222-230 (two half bakes); ×1.3 margin."""
DENOISE_BYTES_PER_TEXEL = 620
"""Extra peak bytes per texel with the denoiser (compositor images and OpenImageDenoise buffers): measured
AO 661-667 and irradiance 665-674 in all, so about 475 more; ×1.3."""
SECONDS_PER_TEXEL_SAMPLE = {k.id: k.seconds_per_texel_sample for k in KINDS.values()}
"""Each kind's ``seconds_per_texel_sample``: rough Cycles CPU seconds per covered texel and sample on this
project's 2-core machine under a plain-colour
world without lights (a fully covered 1024² plane beside a cube, 16 samples: AO 14.4 s, irradiance with 3
bounces 26.3 s); :class:`Speed` scales them for what makes Cycles slower. An upper bound of a map's time, as
every texel is counted covered."""
BOUNCE_FACTOR = 0.05
"""Irradiance per bounce beyond 3: × (1 + 0.05 (K - 3)) (256² floor beside a sphere, 16 samples, colour world:
3 bounces 1.38e-6 s per texel-sample, 8 bounces 1.65e-6)."""
LIGHT_FACTOR = (2.0, 0.3, 8)
"""Irradiance with lamps: × (2.0 + 0.3 min(lights, 8)) (same bake: 1 point light 3.0e-6, 3 lights 3.6e-6; AO
samples no light)."""
WORLD_IMAGE_FACTOR = 6.0
"""An image-textured world (an Environment Texture) evaluates the image at every ray that leaves: × 6, either
map (same bake under forest.exr, 1024×512: AO 4.1e-6, irradiance 7.8e-6 with 3 bounces and 5.7e-6 with 0; lights
add nothing there, so the larger of this and the light factor counts). Lit kinds only: a kind no light shades
(AO) bakes with the world's importance sampling off (``cycles.world_for``): under forest.exr a 256² AO map at 16
samples took 0.32 s (3.0e-7 per texel-sample) instead of 1.69 s, a 16² map at 1 sample 0.04 s instead of 1.43 s."""
WORLD_IMAGE_CALL_SECONDS = 6.0
"""Seconds every Cycles call spends before its first sample under an image-textured world (loading the image and
building its importance map), per 1024×512 image pixels, at least this: measured 3.6-5.1 s per call (16² map at
1 sample, 64² at 16, two calls of an irradiance map) with forest.exr, whatever the map's size."""
PASS_SECONDS = 8.0
"""Longest estimated Cycles call (:func:`seconds`) of a bake: a longer bake is split into sample passes of at most
this, so Ctrl-C (deferred until the current call returns) stops it within 10 s. The estimate is an upper bound
(measured calls take a third to a half of it): a smaller bound made the demo's light maps 12 calls instead of 3
and 14 % slower in CPU time (each call syncs the scene). A call's fixed seconds (:class:`Speed`) come first; a
pass holds at least one sample."""


class Speed:
    """What makes a scene's Cycles bakes slower than SECONDS_PER_TEXEL_SAMPLE: an image-textured world (``world_
    pixels`` > 0, the largest world image's pixels: a factor and fixed seconds per call), ``lights`` (lamps the
    bake sees) and ``bounces`` (irradiance). ``rate(kind)`` seconds per texel-sample, ``call(kind)`` fixed seconds
    of one Cycles call; the world counts for lit kinds only."""

    def __init__(self, world_pixels=0, lights=0, bounces=3):
        self.world_pixels, self.lights, self.bounces = int(world_pixels), int(lights), int(bounces)

    def rate(self, kind):
        base = KINDS[kind].seconds_per_texel_sample
        factor = WORLD_IMAGE_FACTOR if self.world_pixels and KINDS[kind].lit else 1.0
        if KINDS[kind].bounces:
            base *= 1.0 + BOUNCE_FACTOR * max(0, self.bounces - 3)
        if KINDS[kind].lit and self.lights:
            a, b, most = LIGHT_FACTOR
            factor = max(factor, a + b * min(self.lights, most))
        return base * factor

    def call(self, kind):
        if not self.world_pixels or not KINDS[kind].lit:
            return 0.0
        return WORLD_IMAGE_CALL_SECONDS * max(1.0, self.world_pixels / (1024 * 512))

    def describe(self):
        """What the estimate accounts for, for messages ("" for a plain scene)."""
        parts = (["an image-textured world"] if self.world_pixels else []) + \
                ([f"{self.lights} light(s)"] if self.lights else [])
        return ", ".join(parts)


PLAIN = Speed()


RESERVE = 0.8
"""Fraction of the available memory a bake may plan to use (Blender, the scene and the OS need the rest)."""
PANEL_FALLBACK_MEMORY = 8 << 30


def total_memory():
    """Bytes of physical memory, or None if unknown."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def per_texel(maps, denoise=False):
    """Peak bytes per texel of the most expensive of ``maps``."""
    return max(KINDS[m].bytes_per_texel for m in maps) + (DENOISE_BYTES_PER_TEXEL if denoise else 0)


def peak_bytes(width, height, maps, denoise=False):
    """Estimated peak memory in bytes of baking ``maps`` of one (width × height) map."""
    return int(width) * int(height) * per_texel(maps, denoise)


def seconds(width, height, maps, samples, speed=None):
    """Upper bound of the Cycles seconds of baking ``maps`` of one (width × height) map with ``samples`` samples
    under ``speed`` (:class:`Speed`, default a plain scene): texels × samples × rate, plus each call's fixed seconds
    (the calls of :func:`calls`)."""
    speed = speed or PLAIN
    texels = int(width) * int(height)
    return sum(texels * int(samples) * speed.rate(m) + calls(texels, m, samples, speed) * speed.call(m) for m in maps)


def calls(texels, kind, samples, speed=None):
    """How many Cycles calls a fixed-sample bake of ``samples`` makes: two halves for a kind baked in ``halves``
    (irradiance, at 2 samples or more), each in passes of :func:`pass_samples`."""
    halves = [int(samples) // 2, int(samples) - int(samples) // 2] if KINDS[kind].halves and samples >= 2 \
        else [int(samples)]
    most = pass_samples(texels, kind, speed)
    return sum(-(-n // most) for n in halves if n > 0)


def pass_budget(kind, speed=None):
    """Sampling seconds one Cycles call of map ``kind`` may hold: PASS_SECONDS less the call's fixed seconds, but
    never less than those (a world image is loaded at every call: 6 s for 1024x512, 96 s for 4096x2048; a smaller
    budget made every sample a call of its own), so fixed costs stay at most half of a long bake."""
    call = (speed or PLAIN).call(kind)
    return max(PASS_SECONDS - call, call)


def pass_samples(texels, kind, speed=None):
    """The most samples of one Cycles call of map ``kind`` over ``texels`` texels within :func:`pass_budget`
    (at least 1)."""
    speed = speed or PLAIN
    return max(1, int(pass_budget(kind, speed) // (max(1, int(texels)) * speed.rate(kind))))


def check_time(sizes, maps, samples, option="samples", side_option="resolution", speed=None):
    """Raise InputError when baking ``maps`` of every (width, height) in ``sizes`` with ``samples`` is estimated
    (:func:`seconds`, the figures of the progress line) beyond ``core.budget.MAX_SECONDS``. The one line names the
    largest ``option`` (samples) that fits, or where no sample count fits (or ``option`` is None) the largest
    ``side_option``: the side every map is capped at."""
    sizes = [(int(w), int(h)) for w, h in sizes]
    if not sizes:
        return

    def at(n, side=None):
        return 0, sum(seconds(min(w, side or w), min(h, side or h), maps, n, speed) for w, h in sizes)

    if at(samples)[1] <= budget.MAX_SECONDS:
        return
    w, h = max(sizes, key=lambda s: s[0] * s[1])
    what = (f"({' and '.join(maps)} {'up to' if len(set(sizes)) > 1 else 'at'} {w}x{h}"
            f"{f', {len(sizes)} maps each' if len(sizes) > 1 else ''})")
    if option and at(1)[1] <= budget.MAX_SECONDS:
        budget.check(option, int(samples), at, 1, what)
    side = max(max(s) for s in sizes)
    budget.check(side_option, side, lambda r: at(samples, r), 1, f"with {samples} samples {what}")


def largest_side(memory, maps=tuple(KINDS), denoise=False):
    """The largest square side whose bake fits in RESERVE × ``memory`` bytes."""
    return int((RESERVE * memory / per_texel(maps, denoise)) ** 0.5)


def panel_max_side(cap):
    """The panel's resolution limit: the largest side that fits this machine's physical memory, at most ``cap``."""
    return max(1, min(int(cap), largest_side(total_memory() or PANEL_FALLBACK_MEMORY)))


def check(width, height, maps, denoise=False, memory=None, what="resolution"):
    """None when a (width × height) bake of ``maps`` fits RESERVE × ``memory`` (default: the memory available
    now, ``core.budget.available_bytes``, the machine's one measure of it), else the one-line refusal naming the
    largest side that fits."""
    memory = budget.available_bytes() if memory is None else memory
    need = peak_bytes(width, height, maps, denoise)
    if need <= RESERVE * memory:
        return None
    return (f"{article(f'{width}x{height}')} map needs about {need / 2 ** 30:.1f} GiB of memory and {memory / 2 ** 30:.1f} GiB "
            f"is available: the largest {what} that fits is {largest_side(memory, maps, denoise)}")
