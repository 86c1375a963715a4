"""A generated layout made of the charts of the mesh's own UV layers (unwrap._Copies.try_own_layers): made of square
texels, kept where it fills more, refused where it fills less, is uneven, folded, collapsed, shrinks faces or crosses
a hard edge, never for an atlas, and keyed by those layers' UVs."""
import warnings

import bpy
import numpy as np
import pytest

from addon.bake import BakeOptions, bake_lightmaps, unwrap, uvchecks
from addon.bake import uv as uvmod
from addon.blender.scene import corner_uv, corner_vertices
from addon.core import lightmap, pack
from addon.core.io import exr
from tests.support.meshes import added, plain

DENSITY = 40.0


def _copy(obj, name):
    new = bpy.data.objects.new(name, obj.data.copy())
    new.location = obj.location + type(obj.location)((0, 0, 3))
    bpy.context.scene.collection.objects.link(new)
    return new


def _bake(obj, out, **kw):
    opts = BakeOptions(**{"samples": 1, **({} if "resolution" in kw else {"texel_density": DENSITY}), **kw})
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        rep = bake_lightmaps([obj], ["ao"], out, opts)
    return rep["objects"][obj.name]["ao"], [str(w.message) for w in said]


def _texels(obj, entry):
    """The baked layout's triangles in texels of its w x h map, and their world positions."""
    w, h = entry["resolution"]
    return uvmod.triangles_uv(obj, "Lightmap") * (w, h), uvmod.world_triangles(obj)


def _charts(obj):
    """The chart of each face of ``obj``'s "Lightmap" layer (core.pack.chart_labels)."""
    me = obj.data
    faces = np.repeat(np.arange(len(me.polygons)), [p.loop_total for p in me.polygons])
    return pack.chart_labels(faces, corner_vertices(me), corner_uv(me, "Lightmap"))


def _coarsest(tri_texels, tri_world):
    """Area-weighted median over triangles of σ₂, the smaller singular value of the map from the surface to the
    texels: texels per metre in the direction the layout resolves least."""
    e1, e2 = tri_world[:, 1] - tri_world[:, 0], tri_world[:, 2] - tri_world[:, 0]
    n1 = np.linalg.norm(e1, axis=1)
    cross = np.linalg.norm(np.cross(e1, e2), axis=1)
    x2, y2 = np.einsum("ij,ij->i", e1, e2) / n1, cross / n1
    f1, f2 = tri_texels[:, 1] - tri_texels[:, 0], tri_texels[:, 2] - tri_texels[:, 0]
    gx = f1 / n1[:, None]
    gy = (f2 - gx * x2[:, None]) / y2[:, None]
    s2 = np.linalg.svd(np.stack([gx, gy], axis=2), compute_uv=False)[:, 1]
    order = np.argsort(s2)
    c = np.cumsum(cross[order])
    return float(s2[order][np.searchsorted(c, 0.5 * c[-1])])


@pytest.mark.both_versions
def test_a_uv_sphere_is_baked_through_the_grid_its_operator_gives_it(tmp_path):
    """A UV sphere's own layer is one chart, a grid on the unit square over a surface twice as long (around) as high.
    Made of square texels (core.lightmap.isotropic: a 2 × 1 rectangle) and placed by its texels at 40 texels/m, it
    fills at least 0.15 more of its map than the same mesh without the layer (Smart UV Project's layout and the
    joins'), with texels square to unwrap.OWN_ANISOTROPY, resolving at least 40 / √OWN_ANISOTROPY texels per metre
    in its coarsest direction (σ₁σ₂ = 40², σ₁ / σ₂ ≤ OWN_ANISOTROPY), no texel under two faces, every face with
    texels, finite pixels; the map is the window around the chart (at most the margin and a texel of rounding on
    each side)."""
    obj = added(bpy.ops.mesh.primitive_uv_sphere_add)
    bare = plain(_copy(obj, "Bare"))
    entry, _ = _bake(obj, tmp_path / "own")
    smart, _ = _bake(bare, tmp_path / "bare")
    assert entry["unwrap"] == unwrap.OWN + unwrap.RASTER and not smart["unwrap"].startswith(unwrap.OWN)
    assert entry["coverage"] >= smart["coverage"] + 0.15, (entry["coverage"], smart["coverage"])
    texels, world = _texels(obj, entry)
    assert lightmap.texel_anisotropy(texels, world) <= unwrap.OWN_ANISOTROPY
    assert _coarsest(texels, world) >= DENSITY / unwrap.OWN_ANISOTROPY ** 0.5
    assert entry["overlap"] == 0 and lightmap.unmapped_fraction(world, texels) == 0
    pad = 2 * (entry["margin"] + 1)
    assert np.all(np.ptp(texels.reshape(-1, 2), axis=0) + pad >= entry["resolution"]), entry["resolution"]
    channels, _ = exr.read_exr(entry["file"])
    assert all(np.isfinite(c).all() for c in channels.values())


def _grid_sphere(name):
    obj = added(bpy.ops.mesh.primitive_uv_sphere_add)
    obj.name = name
    return obj


def _remap(obj, f):
    me = obj.data
    layer = me.uv_layers["UVMap"]
    uv = np.zeros(len(me.loops) * 2, np.float32)
    layer.data.foreach_get("uv", uv)
    starts = np.zeros(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_start", starts)
    sizes = np.zeros(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_total", sizes)
    uv = f(uv.reshape(-1, 2), starts, sizes).astype(np.float32)
    layer.data.foreach_set("uv", uv.ravel())


def _cubed(uv, starts, sizes):
    return np.stack([uv[:, 0] ** 3, uv[:, 1]], axis=1)          # density 3u² across the grid: 0 at u = 0


def _folded(uv, starts, sizes):
    return np.stack([uv[:, 0], np.abs(2 * uv[:, 1] - 1)], axis=1)   # the grid's halves over one another


def _collapsed(uv, starts, sizes):
    out = uv.copy()
    for s, n in zip(starts[::40], sizes[::40]):                  # every 40th face on a point beside the grid
        out[s:s + n] = 2.0
    return out


@pytest.mark.parametrize("distort", [_cubed, _folded, _collapsed], ids=["uneven", "folded", "collapsed"])
def test_an_own_layer_that_would_fill_more_is_refused_when_it_is_no_light_map(tmp_path, distort):
    """The sphere's grid made uneven (u → u³: the density spread falls to 0), folded (v → |2v − 1|: its halves share
    every texel) or collapsed (every 40th face on a point) still fills more than Smart UV Project's charts, and is
    refused: the layout kept is an unwrapper's, as even, without shared texels and no triangle under
    unwrap.OWN_FLOOR of the median density (a face shrunk on its own is a chart of its own, which
    core.lightmap.isotropic gives its size back; a shrunk region inside a chart is refused by
    core.lightmap.density_floor, tests/core/test_lightmap.py)."""
    obj = _grid_sphere("Distorted")
    _remap(obj, distort)
    entry, _ = _bake(obj, tmp_path / "d")
    assert not entry["unwrap"].startswith(unwrap.OWN), entry["unwrap"]
    texels, world = _texels(obj, entry)
    assert entry["overlap"] == 0 and uvchecks.density_spread([obj]) >= unwrap.MIN_SPREAD
    assert lightmap.unmapped_fraction(world, texels) == 0 and lightmap.density_floor(texels, world) >= unwrap.OWN_FLOOR


def test_an_own_layer_that_fills_less_is_refused(tmp_path, monkeypatch):
    """An ico sphere's own layer (triangles laid in a strip) placed whole by its texels at 128² fills about half what
    Smart UV Project's charts do: with no cuts tried (unwrap.CUTS empty), the layout kept is an unwrapper's. (Its
    strip cut into pieces and joined fills 0.446 against their 0.422, and is kept.)"""
    monkeypatch.setattr(unwrap, "CUTS", ())
    obj = added(bpy.ops.mesh.primitive_ico_sphere_add, subdivisions=3)
    entry, _ = _bake(obj, tmp_path / "i", resolution=128)
    assert not entry["unwrap"].startswith(unwrap.OWN), entry["unwrap"]


def test_an_own_layer_across_a_box_edge_is_refused(tmp_path, monkeypatch):
    """A bevelled cube 0.57 m wide at 10 texels/m (the level benchmark's "Prop 050"): its own layer, the cross a cube
    primitive gets, holds one chart across the box's 90° edges. It is refused (core.merging.CREASE: the light of two
    sides of a hard edge would blend, and the Bevel modifier's UVs across such a chart came out differently from
    run to run): the layout kept is Smart UV Project's; without the rule it would be the cross's."""
    from addon.core import merging

    def bake(out):
        cube = added(bpy.ops.mesh.primitive_cube_add, size=0.5672)
        cube.modifiers.new("Bevel", "BEVEL").width = 0.0567
        return _bake(cube, out, texel_density=10, margin=2)[0]

    assert not bake(tmp_path / "a")["unwrap"].startswith(unwrap.OWN)
    monkeypatch.setattr(merging, "crosses_crease", lambda *a: False)
    assert bake(tmp_path / "b")["unwrap"] == unwrap.OWN + unwrap.RASTER


def test_an_atlas_never_takes_the_own_layers(tmp_path):
    """An atlas of one object (Shared Atlas on, one object selected) keeps an unwrapper's layout: the atlas's UV
    cache key and input hash leave the meshes' own layers out."""
    obj = _grid_sphere("Atlas")
    entry, _ = _bake(obj, tmp_path / "a", atlas=True)
    assert not entry["unwrap"].startswith(unwrap.OWN), entry["unwrap"]


def test_a_layout_made_of_an_own_layer_follows_that_layer(tmp_path):
    """The layout (and so the map's inputs) depends on the own layer's UVs: baked again into the same folder after
    the layer was made uneven, the map is baked again (not "unchanged") through an unwrapper's layout, not the one
    the UV cache holds for the grid; unchanged, it is kept."""
    obj = _grid_sphere("Keyed")
    opts = dict(overwrite=True)
    first = bake_lightmaps([obj], ["ao"], tmp_path / "k", BakeOptions(texel_density=DENSITY, samples=1, **opts))
    assert first["objects"][obj.name]["ao"]["unwrap"] == unwrap.OWN + unwrap.RASTER
    again = bake_lightmaps([obj], ["ao"], tmp_path / "k", BakeOptions(texel_density=DENSITY, samples=1, **opts))
    assert obj.name in again["unchanged"]
    _remap(obj, _cubed)
    third = bake_lightmaps([obj], ["ao"], tmp_path / "k", BakeOptions(texel_density=DENSITY, samples=1, **opts))
    assert obj.name not in third["unchanged"]
    assert not third["objects"][obj.name]["ao"]["unwrap"].startswith(unwrap.OWN)


@pytest.mark.parametrize("size", [dict(resolution=128), dict()], ids=["128", "40 per m"])
def test_a_torus_grid_too_long_for_its_map_is_cut_into_two_pieces_that_stack(tmp_path, size):
    """A torus's own layer made of square texels is a 4 × 1 strip: whole, it could fill at most a quarter of a square
    map. Cut across its length (core.merging.cut_long) into two 2 × 1 pieces of 24 × 12 quads, stacked, it fills at
    least 0.8 of a 128² map and of its window at 40 texels/m, with texels square to unwrap.OWN_ANISOTROPY (at 40
    texels/m resolving at least 40 / √OWN_ANISOTROPY per metre in its coarsest direction), no texel under two faces
    and every face with texels."""
    obj = added(bpy.ops.mesh.primitive_torus_add)
    entry, _ = _bake(obj, tmp_path / "t", **size)
    assert entry["unwrap"] == unwrap.OWN + unwrap.CUT + unwrap.RASTER, entry["unwrap"]
    assert entry["coverage"] >= 0.8, entry["coverage"]
    texels, world = _texels(obj, entry)
    assert lightmap.texel_anisotropy(texels, world) <= unwrap.OWN_ANISOTROPY
    if not size:
        assert _coarsest(texels, world) >= DENSITY / unwrap.OWN_ANISOTROPY ** 0.5
    assert entry["overlap"] == 0 and lightmap.unmapped_fraction(world, texels) == 0
    pieces = _charts(obj)
    assert sorted(np.bincount(pieces)) == [24 * 12, 24 * 12]


def test_a_uv_sphere_grid_at_a_fixed_side_is_cut_into_the_pieces_that_fill_most(tmp_path):
    """A UV sphere's grid made of square texels is a strip 1.63 times longer than high (√(4/3 / 2) · 2π around, π
    high): whole it fills 0.50 of a 128² map. Cut into 4 pieces (unwrap.CUTS), three standing and one lying across
    them (8 of its 32 segments each), it fills at least the 55 % the search aims at, with texels square to unwrap.OWN_ANISOTROPY, no texel under
    two faces and every face with texels."""
    obj = added(bpy.ops.mesh.primitive_uv_sphere_add)
    entry, _ = _bake(obj, tmp_path / "s", resolution=128)
    assert entry["unwrap"] == unwrap.OWN + unwrap.CUT + unwrap.RASTER, entry["unwrap"]
    assert entry["coverage"] >= uvchecks.FILL, entry["coverage"]
    texels, world = _texels(obj, entry)
    assert lightmap.texel_anisotropy(texels, world) <= unwrap.OWN_ANISOTROPY
    assert entry["overlap"] == 0 and lightmap.unmapped_fraction(world, texels) == 0
    pieces = _charts(obj)
    assert sorted(np.bincount(pieces)) == [8 * 16] * 4
