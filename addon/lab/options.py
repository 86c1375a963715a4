"""The comparison labs' options, each declared once: the shadow lab, the SSAO lab, the irradiance
environment map and radiosity. Their scripts' parsers, the operators' properties and the panels are
built from these classes (scripts/_cli.add_options, ui/props.py); ``validate()`` is the one range check.
No bpy here, so ``--help`` starts fast.
"""
import dataclasses
from typing import ClassVar

from ..core.errors import InputError
from ..core.options import Options, option
from ..core.radiosity.solvers import SOLVERS
from ..core.shadow import depth_map
from ..core.ssao import limits as ssao_limits
from ..core.ssao import methods as ssao_methods

SHADOW_METHOD_CHOICES = (
    ("raytraced", "Ray traced", "Cycles with a radius-0 light: the reference"),
    ("planar", "Planar", "Projected shadows onto the receiver plane"),
    ("shadowmap", "Shadow map", "Depth map from the light, numpy lookup with bias and PCF"),
    ("volume_zpass", "Volume z-pass", "Shadow volumes, stencil counted in front of the surface"),
    ("volume_zfail", "Volume z-fail", "Shadow volumes with caps, stencil counted behind the surface"),
    ("eevee", "EEVEE", "EEVEE's virtual shadow maps"),
    ("workbench", "Workbench", "Workbench stencil shadows (sun lights only)"),
)
SHADOW_SCENE_CHOICES = (
    ("sphere", "Sphere", "A sphere over a floor"), ("stairs", "Stairs", "A sphere over steps (non-planar receiver)"),
    ("acne", "Acne", "A box under a grazing sun"), ("plate", "Plate", "A thin plate just above the floor"),
    ("inside", "Inside", "The camera stands inside a shadow volume"))
LIGHT_TYPE_CHOICES = (("sun", "Sun", ""), ("point", "Point", ""), ("spot", "Spot", ""))


@dataclasses.dataclass
class ShadowOptions(Options):
    """One shadow comparison: which methods, at which resolution, with which shadow-map settings."""
    methods: list = option(["raytraced", "planar", "shadowmap", "volume_zpass", "volume_zfail"], "Methods",
                           "comma-separated methods compared with the ray-traced reference", kind=str,
                           choices=SHADOW_METHOD_CHOICES, multiple=True, separator=",", item="shadow method")
    resolution: int = option(128, "Resolution", "render width in pixels (memory is checked first)", minimum=8,
                             maximum=depth_map.MAX_RESOLUTION)
    shadowmap_size: int = option(1024, "Shadow Map Size", "shadow-map size N (N x N texels; memory is checked "
                                 "first)", minimum=2, maximum=depth_map.MAX_SIZE)
    bias: float = option(0.01, "Bias", "constant shadow-map bias in metres", minimum=0.0, unit="LENGTH")
    slope_bias: float = option(2.0, "Slope Bias", "slope-scaled bias in texels: adds B x texel size x "
                               "tan(theta)", minimum=0.0)
    pcf: int = option(1, "PCF", "PCF kernel size K, odd (1 = no filtering)", minimum=1, maximum=15)
    receiver: str = option(None, "Receiver", "plane object for planar shadows (default: Floor)", kind=str)
    samples: int = option(1, "Samples", "Cycles samples of the reference", minimum=1, maximum=4096)
    offset: float = option(1e-3, "Offset", "ray and volume offset along the normal, metres", minimum=0.0,
                           cli=False, ui=False)

    def check(self):
        depth_map.check_pcf(self.pcf)


_SSAO_METHOD_LABELS = {
    "crytek": ("Crytek", "Sphere kernel (seed 000)"),
    "hemisphere": ("Hemisphere", "Normal-oriented hemisphere with bias and range check"),
    "hbao": ("HBAO", "Horizon-based AO (Bavoil 2008)"),
    "gtao": ("GTAO", "Ground-truth AO, cosine-weighted slices (Jimenez 2016)"),
    "eevee": ("EEVEE", "EEVEE's AO pass (first render compiles shaders: about a minute)"),
    "workbench": ("Workbench", "Workbench world-space cavity")}
SSAO_METHOD_CHOICES = tuple((m, *_SSAO_METHOD_LABELS[m]) for m in ssao_methods.ALL_METHODS)
_SSAO_SCENE_LABELS = {
    "plane": ("Plane", "One open plane: k_A = 1 (the sphere kernel reads 0.5)"),
    "corner": ("Box in a Corner", "A box in a room corner (closed forms away from the box)"),
    "thin": ("Thin Occluders", "A thin pole and a thin plate over a floor"),
    "edge": ("Screen Edge", "A box cut by the screen edge"),
    "discontinuity": ("Depth Discontinuity", "A ball floating in front of a wall (halos)")}
SSAO_SCENE_CHOICES = tuple((s, *_SSAO_SCENE_LABELS[s]) for s in ssao_limits.SCENES)


MAX_SSAO_RADIUS = 1e6


@dataclasses.dataclass
class SSAOOptions(Options):
    """One SSAO comparison: methods, frame, samples, radius (= the reference's AO distance).

    ``resolution`` None keeps a .blend's own frame; ``radius`` None is derived from the scene
    (core.ssao.gbuffer.default_radius; a built-in scene: BUILTIN_RADIUS)."""
    #: The built-in scenes' radius when none is given (they are built around it, in metres); not an option.
    BUILTIN_RADIUS: ClassVar[float] = 1.0

    methods: list = option(list(ssao_methods.METHODS), "Methods", "comma-separated methods "
                           "compared with Cycles' ray-traced AO", kind=str, choices=SSAO_METHOD_CHOICES,
                           multiple=True, separator=",", item="SSAO method")
    resolution: int = option(128, "Resolution", "frame width in pixels (height keeps the scene's aspect; a "
                             ".blend keeps its own unless given; memory and time are checked first)", minimum=8,
                             maximum=ssao_limits.MAX_RESOLUTION)
    samples: int = option(16, "Samples", "depth-buffer samples per pixel", minimum=1,
                          maximum=ssao_limits.MAX_SAMPLES)
    radius: float = option(None, "Radius", "SSAO radius in metres = the reference's AO distance (at most 1e6: "
                           "the methods' float32 squares of radius and depth stay finite); default: a tenth of "
                           "the frame's width at the median depth of the visible geometry (a built-in scene: 1 m)",
                           kind=float, above=0, maximum=MAX_SSAO_RADIUS, soft_max=10.0, unit="LENGTH",
                           ui_default=BUILTIN_RADIUS)
    reference_samples: int = option(1024, "Reference Samples", "Cycles AO samples per pixel of the reference "
                                    "(1024: noise <= 0.016)", minimum=1, maximum=ssao_limits.MAX_REFERENCE_SAMPLES)
    blur: bool = option(False, "Depth-Aware Blur", "depth-aware blur after each numpy method")
    seed: int = option(0, "Seed", "random seed of the numpy methods", minimum=0, maximum=2 ** 32 - 1, ui=False)


ENVMAP_METHOD_CHOICES = (("sh9", "Nine SH", "nine spherical harmonics, Ramamoorthi & Hanrahan 2001"),
                         ("brute", "Brute force", "full cosine convolution"))


@dataclasses.dataclass
class EnvmapOptions(Options):
    """The irradiance environment map E(n): method and size."""
    method: str = option("sh9", "Method", "nine spherical harmonics or brute-force convolution",
                         choices=ENVMAP_METHOD_CHOICES)
    width: int = option(64, "Width", "width of the irradiance map, even (height = width/2; memory and time are "
                        "checked first)", minimum=4)

    def check(self):
        if self.width % 2:
            raise InputError(f"width must be an even number >= 4, got {self.width}")


RADIOSITY_SOLVER_CHOICES = tuple((s, label, "") for s, label in zip(
    SOLVERS, ("Jacobi", "Gauss-Seidel", "Progressive refinement")))
MAX_ADAPTIVE = 8
MAX_SAMPLES = 65536


@dataclasses.dataclass
class RadiosityOptions(Options):
    """One radiosity solve and its Cycles comparison."""
    solver: str = option("jacobi", "Solver", "iterative solver", choices=RADIOSITY_SOLVER_CHOICES)
    max_edge: float = option(0.25, "Patch Size", "longest patch edge in metres; refused up front when the N² "
                             "solve would not fit in the available memory or would take more than an hour",
                             above=0, unit="LENGTH")
    adaptive: int = option(0, "Adaptive Rounds", "rounds of adaptive subdivision", minimum=0, maximum=MAX_ADAPTIVE)
    samples: int = option(64, "Cycles Samples", "Cycles samples of the comparison bake", minimum=1,
                          maximum=MAX_SAMPLES)
    tol: float = option(1e-5, "Tolerance", "relative residual to stop at", above=0, maximum=0.5, ui=False)
    compare: bool = option(True, "Compare with Cycles", "bake the same objects with Cycles and report the "
                           "difference", flag="--no-compare")
    compare_solvers: bool = option(False, "Compare Solvers", "also run the other two solvers on the same form "
                                   "factors for the convergence chart and CSV (progressive refinement alone can "
                                   "take longer than the solve)")


RAYTRACE_METHOD_CHOICES = (("raycast", "Ray casting", "primary ray, local model at the first hit, shadow rays"),
                           ("whitted", "Whitted", "ray casting plus recursive mirror and refraction rays (seed 004 eq. 2)"))
RAYTRACE_SCENE_CHOICES = (
    ("diffuse", "Diffuse", "A diffuse plane and sphere under a point light"),
    ("mirror", "Mirror Sphere", "A perfect mirror sphere on a diffuse plane"),
    ("glass", "Glass Sphere", "A clear glass sphere (IOR 1.5) on a diffuse plane"),
    ("walls", "Two Walls", "Two diffuse walls facing each other (interreflection Whitted leaves out)"),
    ("area", "Area Light", "A diffuse plane and sphere under an area light and a grey sky (left out by Whitted)"),
    ("grazing", "Grazing", "A mirror plane seen at grazing angles"),
    ("ior1", "IOR 1", "A glass sphere of IOR 1 (invisible to Cycles; Whitted's shadow ray still stops at it)"),
    ("tir", "TIR", "A glass sphere of IOR 2.4: total internal reflection"))
MAX_RAYTRACE_DEPTH = 64
RAYTRACE_ENGINE_CHOICES = (("numpy", "numpy BVH", "the add-on's numpy BVH, all rays of a bounce at once (measured "
                                                   "faster or equal on most scenes, docs/raytrace.md)"),
                           ("bvhtree", "Blender BVHTree", "mathutils BVHTree, one call per ray (faster on glass)"))


@dataclasses.dataclass
class RaytraceOptions(Options):
    """One ray-casting or Whitted render of the scene camera and its Cycles comparison."""
    method: str = option("whitted", "Method", "ray casting or Whitted ray tracing", choices=RAYTRACE_METHOD_CHOICES)
    max_depth: int = option(4, "Max Depth", "reflection and refraction bounces (Whitted; Cycles' glossy and "
                            "transmission bounces of the comparison)", minimum=0, maximum=MAX_RAYTRACE_DEPTH)
    resolution: int = option(64, "Resolution", "image width in pixels (height keeps the scene's aspect)",
                             minimum=8, maximum=2048)
    engine: str = option("numpy", "Engine", "ray-triangle intersection engine", choices=RAYTRACE_ENGINE_CHOICES)
    samples: int = option(16, "Cycles Samples", "Cycles samples per pixel of each of the two comparison renders",
                          minimum=1, maximum=4096)
    compare: bool = option(True, "Compare with Cycles", "render the same camera with Cycles and report the "
                           "difference", flag="--no-compare")


REFLECTION_METHOD_CHOICES = (
    ("latlong", "Lat-long", "Lookup of r in the lat-long map captured at the capture point"),
    ("cube", "Cube map", "Lookup of r in a cube map with as many texels as the lat-long map"),
    ("sphere", "Sphere map", "Lookup of r in a sphere map with as many texels as the lat-long map"),
    ("raytraced", "Ray traced", "Cycles' mirror (Glossy, roughness 0): the reference"))
REFLECTION_SCENE_CHOICES = (
    ("sphere", "Sphere", "A mirror sphere under a sky: the maps' filtering error only"),
    ("nearby", "Nearby geometry", "A mirror sphere between emissive boxes, moved away from the capture point"),
    ("flat", "Flat mirror", "A flat mirror facing an emissive box"),
    ("concave", "Concave", "A mirror bowl that reflects itself"))


@dataclasses.dataclass
class ReflectionOptions(Options):
    """One reflection-mapping comparison: the map types against Cycles' mirror on the same pixels."""
    methods: list = option(["latlong", "cube", "sphere", "raytraced"], "Methods", "comma-separated methods "
                           "compared with Cycles' mirror", kind=str, choices=REFLECTION_METHOD_CHOICES,
                           multiple=True, separator=",", item="reflection method")
    resolution: int = option(64, "Resolution", "render width in pixels (height keeps the scene's aspect)",
                             minimum=8, maximum=2048)
    map_size: int = option(64, "Map Size", "lat-long map height H (2H x H texels, captured at 4H x 2H: about "
                           "400 H^2 bytes); the cube and sphere maps get as many texels (faces of H/sqrt(3), a "
                           "sphere of H sqrt(2))", minimum=4, maximum=1024)
    object: str = option(None, "Object", "the mirror mesh (default: the object named Mirror)", kind=str)
    samples: int = option(1, "Samples", "Cycles samples of the reference and the capture (1 is exact for "
                          "emissive surroundings and a world; lit diffuse surroundings need more)",
                          minimum=1, maximum=4096)
