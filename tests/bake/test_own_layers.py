"""A generated layout made of the charts of the mesh's own UV layers (unwrap._Copies.try_own_layers): kept where it
fills more, refused where its density is uneven, a chart folds over itself or a face gets no texel, and keyed by
those layers' UVs."""
import warnings

import bpy
import numpy as np
import pytest

from addon.bake import BakeOptions, bake_lightmaps, unwrap, uvchecks
from addon.bake import uv as uvmod
from addon.core import lightmap
from addon.core.errors import ILWarning
from addon.core.io import exr
from tests.support.meshes import added, plain


def _copy(obj, name):
    new = bpy.data.objects.new(name, obj.data.copy())
    new.location = obj.location + type(obj.location)((0, 0, 3))
    bpy.context.scene.collection.objects.link(new)
    return new


def _fill(obj, side):
    return float(lightmap.coverage_mask(uvmod.triangles_uv(obj, "Lightmap"), side, side).mean())


def _bake(obj, out, **kw):
    opts = BakeOptions(**{"samples": 1, **({} if "texel_density" in kw else {"resolution": 128}), **kw})
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        rep = bake_lightmaps([obj], ["ao"], out, opts)
    return rep, [str(w.message) for w in said if issubclass(w.category, ILWarning)]


@pytest.mark.both_versions
@pytest.mark.parametrize("kind, rings", [("torus", 0), ("uv_sphere", 16)])
def test_a_primitive_is_baked_through_the_grid_its_operator_gives_it(tmp_path, kind, rings):
    """A torus's and a UV sphere's own layer is one chart, a grid on the unit square (the sphere's first and last
    rows are triangles: 1 − 1/rings of it covered). Placed by its texels in a 128² map, at least m − 1 texels from the
    border (m: the layout's margin) and a texel of rounding each side, it fills at least
    (1 − 1/rings) ((128 − 2 (m − 1) − 2) / 128)², at the texel density of Smart UV Project's layout (spread at least
    MIN_SPREAD), no texel under two faces, none of the surface without texels; the same mesh without the layer,
    Smart UV Project's and the joins', fills under 0.55 and gets a low-fill line."""
    obj = added(getattr(bpy.ops.mesh, f"primitive_{kind}_add"))
    bare = plain(_copy(obj, "Bare"))
    rep, said = _bake(obj, tmp_path / "own")
    entry = rep["objects"][obj.name]["ao"]
    m = entry["margin"]
    bound = (1 - (1 / rings if rings else 0)) * ((128 - 2 * (m - 1) - 2) / 128) ** 2
    assert entry["unwrap"] == unwrap.OWN + unwrap.RASTER, entry["unwrap"]
    assert _fill(obj, 128) == pytest.approx(entry["coverage"]) and entry["coverage"] >= bound, (entry, bound)
    assert "low_fill" not in entry and not any("cover only" in w for w in said), said
    assert entry["overlap"] == 0 and uvchecks.density_spread([obj]) >= unwrap.MIN_SPREAD
    assert lightmap.unmapped_fraction(uvmod.world_triangles(obj), uvmod.triangles_uv(obj, "Lightmap")) == 0
    channels, _ = exr.read_exr(entry["file"])
    assert all(np.isfinite(c).all() for c in channels.values())
    other, said = _bake(bare, tmp_path / "bare")
    smart = other["objects"][bare.name]["ao"]
    assert not smart["unwrap"].startswith(unwrap.OWN) and smart["coverage"] < 0.55 and "low_fill" in smart


def _grid_torus(name):
    obj = added(bpy.ops.mesh.primitive_torus_add)
    obj.name = name
    return obj


def _remap(obj, f):
    me = obj.data
    layer = me.uv_layers["UVMap"]
    uv = np.zeros(len(me.loops) * 2, np.float32)
    layer.data.foreach_get("uv", uv)
    starts = np.zeros(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_start", starts)
    uv = f(uv.reshape(-1, 2), starts).astype(np.float32)
    layer.data.foreach_set("uv", uv.ravel())


def _cubed(uv, starts):
    return np.stack([uv[:, 0] ** 3, uv[:, 1]], axis=1)          # density 3u² across the grid: 0 at u = 0


def _folded(uv, starts):
    return np.stack([uv[:, 0], np.abs(2 * uv[:, 1] - 1)], axis=1)   # the grid's halves over one another


def _collapsed(uv, starts):
    out = uv.copy()
    for s in starts[::40]:                                       # every 40th quad on a point beside the grid
        out[s:s + 4] = 2.0
    return out


@pytest.mark.parametrize("distort", [_cubed, _folded, _collapsed], ids=["uneven", "folded", "collapsed"])
def test_an_own_layer_that_would_fill_more_is_refused_when_it_is_no_light_map(tmp_path, distort):
    """The torus's grid made uneven (u → u³: the density spread falls to 0), folded (v → |2v − 1|: its halves share
    every texel) or collapsed (every 40th face on a point: faces without texels) still fills more than
    Smart UV Project's charts, and is refused: the layout kept is an unwrapper's, as even, without shared texels and
    with a texel for every face."""
    obj = _grid_torus("Distorted")
    _remap(obj, distort)
    rep, _ = _bake(obj, tmp_path / "d")
    entry = rep["objects"][obj.name]["ao"]
    assert not entry["unwrap"].startswith(unwrap.OWN), entry["unwrap"]
    assert entry["overlap"] == 0 and uvchecks.density_spread([obj]) >= unwrap.MIN_SPREAD
    assert lightmap.unmapped_fraction(uvmod.world_triangles(obj), uvmod.triangles_uv(obj, "Lightmap")) == 0


def test_an_own_layer_across_a_box_edge_is_refused(tmp_path, monkeypatch):
    """A bevelled cube 0.57 m wide at 10 texels/m (the level benchmark's "Prop 050"): its own layer, the cross a cube
    primitive gets, holds one chart across the box's 90° edges, and placed by its texels fills 0.37 of its 27 x 21
    map against Smart UV Project's 0.36. It is refused (core.merging.CREASE: the light of two sides of a hard edge
    would blend, and the Bevel modifier's UVs across such a chart came out differently from run to run): the layout
    kept is Smart UV Project's; without the rule it would be the cross's."""
    from addon.core import merging

    def bake(out):
        cube = added(bpy.ops.mesh.primitive_cube_add, size=0.5672)
        cube.modifiers.new("Bevel", "BEVEL").width = 0.0567
        return _bake(cube, out, texel_density=10, margin=2)[0]["objects"][cube.name]["ao"]

    assert not bake(tmp_path / "a")["unwrap"].startswith(unwrap.OWN)
    monkeypatch.setattr(merging, "crosses_crease", lambda *a: False)
    assert bake(tmp_path / "b")["unwrap"] == unwrap.OWN + unwrap.RASTER


def test_a_layout_made_of_an_own_layer_follows_that_layer(tmp_path):
    """The layout (and so the map's inputs) depends on the own layer's UVs: baked again into the same folder after the
    layer was made uneven, the map is baked again (not "unchanged") through an unwrapper's layout, not the one the UV
    cache holds for the grid; unchanged, it is kept."""
    obj = _grid_torus("Keyed")
    opts = dict(overwrite=True)
    first, _ = _bake(obj, tmp_path / "k", **opts)
    assert first["objects"][obj.name]["ao"]["unwrap"] == unwrap.OWN + unwrap.RASTER
    again, _ = _bake(obj, tmp_path / "k", **opts)
    assert obj.name in again["unchanged"]
    _remap(obj, _cubed)
    third, _ = _bake(obj, tmp_path / "k", **opts)
    assert obj.name not in third["unchanged"]
    assert not third["objects"][obj.name]["ao"]["unwrap"].startswith(unwrap.OWN)


def test_at_a_texel_density_the_grid_is_baked_in_a_window_around_it(tmp_path):
    """At 40 texels/m the torus's grid (one chart, square in its layer) keeps the texel density of Smart UV Project's
    layout and is baked in the window its charts and margins need: C covered texels in a square chart of side √C,
    with m texels of margin and a texel of rounding each side, fill at least C / (√C + 2 m + 2)²."""
    obj = _grid_torus("Windowed")
    rep, said = _bake(obj, tmp_path / "w", texel_density=40)
    entry = rep["objects"][obj.name]["ao"]
    w, h = entry["resolution"]
    covered = entry["coverage"] * w * h
    assert entry["unwrap"] == unwrap.OWN + unwrap.RASTER and "low_fill" not in entry, entry
    assert entry["coverage"] >= covered / (covered ** 0.5 + 2 * entry["margin"] + 2) ** 2 > 0.8
    assert covered == pytest.approx(40 ** 2 * uvmod.world_area(obj), rel=0.1)
