"""Node groups against their numpy twins and against Cycles' own BSDFs, from real renders (bpy)."""
import bpy
import numpy as np
import pytest

from addon.blender import compat
from addon.core import brdf
from addon.blender import render
from addon.lab.bench import shading as sb
from addon.blender import scene as sc
from addon.nodes import material
from addon.nodes.models import MODELS

#: Every registered model's public group (nodes/models): a model added there is swept here too.
MODEL_GROUPS = [m.group for m in MODELS]
#: The groups whose twin mapping is also written out here (:func:`_twin`), independent of the records'.
WRITTEN_OUT = ("IL Phong", "IL Blinn-Phong", "IL Oren-Nayar", "IL Cook-Torrance")


def _c(x):
    return np.asarray(x, float)[:3]


def _twin(name, n, v, i):
    """Group inputs -> the numpy twin, written out here (independent of the records' own mapping)."""
    l, I = _c(i["Light Vector"]), _c(i["Light Color"])
    if name in ("IL Phong", "IL Blinn-Phong"):
        fn = brdf.phong if name == "IL Phong" else brdf.blinn_phong
        return fn(n, l, v, I, ka=i.get("Ka", 0.1), ambient_light=(0.2, 0.2, 0.2), kd=(0.8, 0.8, 0.8),
                  ks=i["Ks"], shininess=i["Shininess"], emission=(0, 0, 0), normalized=i.get("Normalized", 0.0))
    if name == "IL Oren-Nayar":
        return brdf.oren_nayar(n, l, v, I, albedo=(0.8, 0.8, 0.8), sigma=i["Sigma"])
    return brdf.cook_torrance(n, l, v, I, kd=(0.2, 0.2, 0.2), ks=1.0, F0=i["F0"], roughness=i["Roughness"],
                              distribution=i["Distribution"], geometry=i["Geometry"])


@pytest.mark.parametrize("name", MODEL_GROUPS)
def test_node_group_equals_its_twin_over_a_dense_direction_sweep(name):
    """Every registered model: its group, rendered over its record's sweep, equals its record's numpy twin (and,
    for the models written out above, that twin is the written-out mapping)."""
    cases = sb.sweep_cases(name)  # parameter sets x light vectors: frontal, oblique, grazing, from behind
    assert cases, f"{name}: its record has no sweep cases"
    results = sb.render_group_sweep(name, cases, size=96)
    peak = max(np.max(sb.twin(name, r["n"], r["v"], r["inputs"])) for r in results)
    pixels = 0
    for r in results:
        assert len(r["n"]) > 100
        # the sphere seen by an orthographic camera covers every normal of the visible hemisphere
        assert np.min(r["n"] @ r["v"]) < 0.3 and np.max(r["n"] @ r["v"]) > 0.99
        ref = sb.twin(name, r["n"], r["v"], r["inputs"])
        if name in WRITTEN_OUT:
            assert np.array_equal(ref, _twin(name, r["n"], r["v"], r["inputs"])), r["inputs"]
        err = np.max(np.abs(r["L"] - ref))
        assert err <= 1e-4 * peak, (r["inputs"], err, peak)
        pixels += len(r["n"])
    assert pixels > 2000


@pytest.mark.parametrize("name", ["IL Blinn-Phong", "IL Cook-Torrance"])
def test_lights_opposite_the_view_give_the_twin(name):
    """n.h and v.h come from l + v, which shrinks to 0 as the light turns to -v (behind the surface seen by the
    camera): lights 150, 160 and 170 degrees from v light a grazing rim (pixels where the light adds
    something, counted), one exactly opposite leaves the ambient term; every pixel finite and the twin's
    within 1e-4 of the peak."""
    cases = [dict(case, **{"Light Vector": (np.sin(t), -np.cos(t), 0.0), "Light Color": (0.9, 0.7, 0.5)})
             for case in sb.SWEEP_CASES[name][:2] for t in np.radians([150.0, 160.0, 170.0, 180.0])]
    results = sb.render_group_sweep(name, cases, size=128)
    peak = max(np.max(_twin(name, r["n"], r["v"], r["inputs"])) for r in results)
    for r in results:
        ref = _twin(name, r["n"], r["v"], r["inputs"])
        dark = _twin(name, r["n"], r["v"], dict(r["inputs"], **{"Light Color": (0.0, 0.0, 0.0)}))
        lit = np.count_nonzero((ref - dark).max(axis=1) > 1e-3 * peak)
        assert np.all(np.isfinite(r["L"])) and (lit > 4 or r["inputs"]["Light Vector"][0] < 1e-6), (r["inputs"], lit)
        err = np.max(np.abs(r["L"] - ref))
        assert err <= 1e-4 * peak, (r["inputs"], err, peak)


def test_oren_nayar_sigma0_physical_equals_diffuse_bsdf_within_3_standard_errors():
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 40
    scene.render.resolution_percentage = 100
    ball = sc.sphere(scene, "Ball", 1.0, segments=96, rings=48)
    sc.camera(scene, "Cam", (0, -10, 0), target=(0, 0, 0), ortho_scale=2.2)
    sc.world(scene, 0.0)
    point = sc.light(scene, "Point", "POINT", 120.0, location=(1.5, -2.0, 1.0), radius=0.0)
    sun = sc.light(scene, "Sun", "SUN", 1.5, rotation=sc.deg(50, 0, 200))
    for lamp in (point, sun):
        lamp.data.use_shadow = False  # no terminator self-shadowing of the faceted sphere: shading only
    scene.view_layers[0].use_pass_normal = True
    il, _ = material.assign_shading_model(scene, [ball], "OREN_NAYAR", attenuation="PHYSICAL",
                                          params={"Albedo": (0.7, 0.7, 0.7), "Sigma": 0.0})
    diffuse = sb.closure_material("Diffuse", "DIFFUSE", color=(0.7, 0.7, 0.7), roughness=0.0)
    samples = 16
    runs = {}
    for label, mat, seed in (("il", il, 1), ("d1", diffuse, 1), ("d2", diffuse, 2)):
        sb.assign(ball, mat)
        render.cycles_cpu(scene, samples=samples, seed=seed)
        scene.cycles.max_bounces = 0
        passes = render.render_layers(scene)
        runs[label] = passes["Combined"][..., :3].astype(float)
        normal = passes["Normal"]
    hit = np.linalg.norm(normal, axis=-1) > 0.99  # whole-pixel sphere coverage only
    d1, d2, il_img = runs["d1"][hit], runs["d2"][hit], runs["il"][hit]
    assert np.mean(np.abs(d1 - d2)) > 0  # the Cycles estimate is noisy (two delta lights: light selection)
    # bins by brightness; standard error of the mean of (d1 + d2)/2 from the spread of d1 - d2
    est = (d1 + d2) / 2
    order = np.argsort(il_img[:, 1])
    for chunk in np.array_split(order, 12):
        diff = np.mean(il_img[chunk] - est[chunk], axis=0)
        se = np.std(d1[chunk] - d2[chunk], axis=0, ddof=1) / 2 / np.sqrt(len(chunk))
        assert np.all(np.abs(diff) <= 3 * se + 1e-6), (diff, se)
        mean = np.mean(est[chunk], axis=0)
        assert np.all((3 * se < 0.02 * mean) | (mean < 0.05))  # sharp enough to see a 2 % error
    # closed-form ceiling: albedo 0.7 times the point's I at the nearest surface point plus the sun's S/pi
    d = np.linalg.norm([1.5, -2.0, 1.0]) - 1.0
    ceiling = 0.7 * (120.0 / (4 * np.pi ** 2 * d * d) + 1.5 / np.pi)
    assert 0.3 < np.max(il_img) <= ceiling


EDGE_CASES = [
    ("IL Phong", {"Shininess": 0.0, "Ks": 1.0, "Normalized": 0.0}),
    ("IL Phong", {"Shininess": 1e4, "Ks": 1.0, "Normalized": 1.0}),
    ("IL Blinn-Phong", {"Shininess": 0.0, "Ks": 1.0, "Normalized": 1.0}),
    ("IL Blinn-Phong", {"Shininess": 1e4, "Ks": 1.0, "Normalized": 1.0}),
    ("IL Oren-Nayar", {"Sigma": 10.0}),
    ("IL Cook-Torrance", {"Roughness": 0.0, "Distribution": 0.0, "Geometry": 0.0, "F0": 1.0}),
    ("IL Cook-Torrance", {"Roughness": 0.0, "Distribution": 1.0, "Geometry": 1.0, "F0": 1.0}),
]
EDGE_LIGHTS = [(0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 0.0)]  # front, grazing, behind, none
#: bounds from the clamps: (n+2)/2 lobe, Oren-Nayar A + B <= 1.45, CT <= 1 / (4e-4 m^2) with m >= 1e-3
EDGE_BOUND = {"IL Phong": 1.1 + 5002, "IL Blinn-Phong": 1.1 + 1252, "IL Oren-Nayar": 2.0, "IL Cook-Torrance": 2.6e9}


def _edge_scene(size):
    objs = [(name, dict(params, **{"Light Vector": l})) for name, params in EDGE_CASES for l in EDGE_LIGHTS]
    scene, spheres = sb.sphere_grid("IL edges", len(objs), size, segments=32, rings=16)
    for k, (obj, (name, inputs)) in enumerate(zip(spheres, objs)):
        sb.assign(obj, sb.group_material(f"edge {k}", name, inputs))
    return scene, objs


def _check_edges(passes, objs):
    index = np.rint(passes[compat.OBJECT_INDEX_PASS]).astype(int) if compat.OBJECT_INDEX_PASS in passes else None
    rgb = passes["Combined"][..., :3]
    assert np.all(np.isfinite(rgb)) and np.all(rgb >= -1e-6) and np.max(rgb) <= max(EDGE_BOUND.values())
    if index is not None:
        for k, (name, _) in enumerate(objs):
            m = index == k + 1
            assert np.any(m)
            assert np.max(rgb[m]) <= EDGE_BOUND[name], (name, np.max(rgb[m]))


def test_edges_finite_and_bounded_in_cycles():
    scene, objs = _edge_scene(96)
    render.cycles_cpu(scene, samples=1)
    scene.cycles.max_bounces = 0
    _check_edges(render.render_layers(scene), objs)


@pytest.mark.eevee
def test_edges_finite_and_bounded_in_eevee():
    scene, objs = _edge_scene(48)
    scene.render.engine = compat.EEVEE
    scene.eevee.taa_render_samples = 1
    passes = render.render_layers(scene)
    _check_edges({"Combined": passes["Combined"]}, objs)
    # roughness clamp keeps the GGX mirror highlight on screen, the IL Phong n = 0 sphere is lit
    assert np.max(passes["Combined"][..., :3]) > 1.0


def test_node_groups_directional_albedo_rendered():
    """One Cycles render of the groups' directional albedo (every pixel one light direction through the half
    vector, 1 sample): it equals the twin's on the same directions and keeps the energy bounds."""
    results = sb.render_group_albedo(size=64)
    assert len(results) == len(sb.ALBEDO_CASES)
    for r in results:
        assert r["pixels"] == 64 * 64, r
        # node group and numpy twin, same directions and shading normal (the Normal pass: Cycles rounds normals,
        # compat.CYCLES_NORMAL_ERROR): float32 only (the two cannot drift apart)
        assert r["albedo"] == pytest.approx(r["twin"], abs=1e-4), r
        t = np.radians(r["theta_v"])
        # the 64^2 midpoint rule over-estimates by <= 1.1e-3 here (measured against the exact integrals)
        if r["group"] == "IL Oren-Nayar":
            s2 = r["inputs"]["Sigma"] ** 2
            A, B = 1 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)   # Oren & Nayar 1994
            T = 2 / np.pi * (np.sin(t) * (t / 2 - np.sin(2 * t) / 4) + np.tan(t) * (1 - np.sin(t) ** 3) / 3)
            assert r["albedo"] == pytest.approx(A + B * T, abs=1.5e-3), r
        else:
            assert r["albedo"] <= 1.0 + 1.5e-3, r  # energy-normalised Phong and Blinn-Phong
            if r["theta_v"] == 0.0:
                assert r["albedo"] == pytest.approx(1.0, abs=1.5e-3), r  # exact normalisation at v = n
