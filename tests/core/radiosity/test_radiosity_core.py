"""Radiosity (seed 004) against closed forms: form factors, solvers, subdivision. No bpy."""
import numpy as np
import pytest

from addon.core import analytic
from addon.core.radiosity import atlas as rad_atlas
from addon.core.radiosity import form_factors
from addon.core.radiosity import gather
from addon.core.radiosity import patches as rad_patches
from addon.core.radiosity import solvers as rad_solvers
from addon.core.radiosity import subdivision as rad_subdivision
from addon.core.radiosity import visibility
from addon.core.errors import InputError

H = 1.0
CUBE = [[(-H, -H, -H), (H, -H, -H), (H, H, -H), (-H, H, -H)],   # inward-facing faces of a closed cube
        [(-H, -H, H), (-H, H, H), (H, H, H), (H, -H, H)],
        [(-H, -H, -H), (-H, H, -H), (-H, H, H), (-H, -H, H)],
        [(H, -H, -H), (H, -H, H), (H, H, H), (H, H, -H)],
        [(-H, -H, -H), (-H, -H, H), (H, -H, H), (H, -H, -H)],
        [(-H, H, -H), (H, H, -H), (H, H, H), (-H, H, H)]]


def cube(n, rho=0.5, le=1.0):
    meshes = [{"name": f"f{k}", "vertices": np.array(q), "faces": [(0, 1, 2, 3)], "rho": rho, "emission": le}
              for k, q in enumerate(CUBE)]
    return rad_subdivision.subdivide_to_size(rad_patches.patches_from_meshes(meshes), 2 * H / n + 1e-9)


def plates(n, c=1.0):
    m = [{"name": "a", "vertices": np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), "faces": [(0, 1, 2, 3)],
          "rho": 0.5, "emission": 1.0},
         {"name": "b", "vertices": np.array([(0, 0, c), (0, 1, c), (1, 1, c), (1, 0, c)]), "faces": [(0, 1, 2, 3)],
          "rho": 0.5, "emission": 0.0}]
    return rad_subdivision.subdivide_to_size(rad_patches.patches_from_meshes(m), 1.0 / n + 1e-9)


def parallel_plates_exact(X, Y):
    """Howell catalog C-11: directly opposed parallel rectangles a x b at distance c, X = a/c, Y = b/c."""
    return 2 / (np.pi * X * Y) * (
        np.log(np.sqrt((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y)))
        + X * np.sqrt(1 + Y * Y) * np.arctan(X / np.sqrt(1 + Y * Y))
        + Y * np.sqrt(1 + X * X) * np.arctan(Y / np.sqrt(1 + X * X)) - X * np.arctan(X) - Y * np.arctan(Y))


def test_point_to_polygon_matches_disk_and_corner_rectangle():
    # parallel square a x b above a point at one corner, height c (REFERENCE.md §3, Howell B-3)
    a, b, c = 1.0, 2.0, 0.7
    poly = np.array([[[0, 0, c], [0, b, c], [a, b, c], [a, 0, c]]])
    X, Y = a / c, b / c
    exact = (X / np.sqrt(1 + X * X) * np.arctan(Y / np.sqrt(1 + X * X))
             + Y / np.sqrt(1 + Y * Y) * np.arctan(X / np.sqrt(1 + Y * Y))) / (2 * np.pi)
    ff = form_factors.point_polygon_form_factors(np.zeros((1, 3)), np.array([[0, 0, 1.0]]), poly)
    assert ff[0, 0] == pytest.approx(exact, rel=1e-12)
    # a polygon facing away emits nothing toward the point
    assert form_factors.point_polygon_form_factors(np.zeros((1, 3)), np.array([[0, 0, 1.0]]), poly[:, ::-1])[0, 0] == 0


def test_horizon_clipping_half_plane():
    """A huge wall through the point, standing on its tangent plane, clipped half below: F -> 1/2 (REFERENCE §3)."""
    L = 1e4
    wall = np.array([[[1e-3, -L, -L], [1e-3, -L, L], [1e-3, L, L], [1e-3, L, -L]]])   # facing -X, toward the point
    ff = form_factors.point_polygon_form_factors(np.zeros((1, 3)), np.array([[0, 0, 1.0]]), wall)
    assert ff[0, 0] == pytest.approx(0.5, abs=1e-3)


def test_rows_of_a_closed_scene_sum_to_one():
    p = cube(4)
    F = form_factors.form_factors(p)
    assert np.allclose(F.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(np.diag(F) == 0) and np.all(F >= 0)


def test_reciprocity_improves_with_quadrature():
    p = cube(4)
    errs = []
    for q in (1, 3):
        AF = p.area[:, None] * form_factors.form_factors(p, quadrature=q)
        errs.append(np.max(np.abs(AF - AF.T)) / np.max(AF))
    assert errs[1] < 0.01 and errs[1] < errs[0] / 5
    # far-apart small patches: reciprocity already with one point
    pl = plates(2, c=20.0)
    AF = pl.area[:, None] * form_factors.form_factors(pl)
    assert np.allclose(AF, AF.T, rtol=1e-3, atol=0)


@pytest.mark.parametrize("n,tol", [(4, 0.012), (8, 0.003)])
def test_parallel_plates_against_analytic(n, tol):
    p = plates(n)
    F = form_factors.form_factors(p)
    a, b = p.owner == 0, p.owner == 1
    total = (p.area[a, None] * F[np.ix_(a, b)]).sum() / p.area[a].sum()
    assert total == pytest.approx(parallel_plates_exact(1.0, 1.0), rel=tol)
    assert parallel_plates_exact(1.0, 1.0) == pytest.approx(0.19982, abs=1e-5)


def test_visibility_matrix_blocks_plates():
    p = plates(2)
    blocker = rad_patches.patches_from_meshes([{"name": "blk", "vertices": np.array([(-1, -1, .5), (2, -1, .5), (2, 2, .5), (-1, 2, .5)]),
                                      "faces": [(0, 1, 2, 3)], "rho": 0.5, "emission": 0.0}])
    both = rad_patches.Patches(np.concatenate([p.corners, blocker.corners]), np.concatenate([p.rho, blocker.rho]),
                     np.concatenate([p.emission, blocker.emission]), np.r_[p.owner, 2],
                     np.r_[p.is_tri, blocker.is_tri], np.r_[p.source, 0])
    V = visibility.visibility_numpy(both)
    a, b = np.flatnonzero(both.owner == 0), np.flatnonzero(both.owner == 1)
    assert np.all(V[np.ix_(a, b)] == 0)               # the blocker hides the plates from each other
    assert np.all(V[np.ix_(b, [len(both) - 1])] == 1)  # the upper plate sees the blocker's top side
    assert np.all(V[np.ix_(a, [len(both) - 1])] == 0)  # the lower plate is behind it
    F = form_factors.form_factors(both, V)
    assert np.all(F[np.ix_(a, b)] == 0) and np.all(F[b, -1] > 0) and np.all(F[a, -1] == 0)


@pytest.mark.parametrize("solver", ["jacobi", "gauss_seidel", "progressive", "direct"])
def test_closed_enclosure_b_equals_e_over_one_minus_rho(solver):
    rho, le = 0.6, 2.0
    p = cube(3, rho=rho, le=le)
    F = form_factors.form_factors(p)
    sol = rad_solvers.solve(F, p.rho, p.emission, p.area, solver, tol=1e-9)
    assert np.allclose(sol.B, np.pi * le / (1 - rho), rtol=1e-6)
    assert np.allclose(rad_solvers.irradiance(F, sol.B), np.pi * le / (1 - rho), rtol=1e-6)


def test_jacobi_k_iterations_are_k_bounces():
    rho, le, K = 0.6, 1.0, 3
    p = cube(2, rho=rho, le=le)
    sol = rad_solvers.solve_jacobi(form_factors.form_factors(p), p.rho, p.emission, tol=0, max_iter=K)
    assert np.allclose(sol.B, np.pi * le * (1 - rho ** (K + 1)) / (1 - rho), rtol=1e-9)


def test_solvers_agree_on_cornell_and_slow_down_as_rho_grows():
    p = analytic.cornell_patches(max_edge=0.6)
    F = form_factors.form_factors(p, visibility.visibility_numpy(p))
    ref = rad_solvers.solve_direct(F, p.rho, p.emission).B
    for s in rad_solvers.SOLVERS:
        sol = rad_solvers.solve(F, p.rho, p.emission, p.area, s, tol=1e-7)
        assert sol.converged
        assert np.allclose(sol.B, ref, rtol=1e-4, atol=1e-6 * ref.max()), s
        assert sol.residuals[-1] < 1e-7
    iters = {s: [] for s in rad_solvers.SOLVERS}
    for rho in (0.3, 0.7, 0.95):
        r = np.where(p.rho > 0, rho, 0.0)
        for s in rad_solvers.SOLVERS:
            iters[s].append(rad_solvers.solve(F, r, p.emission, p.area, s, tol=1e-6).iterations)
    for s, it in iters.items():
        assert it[0] < it[1] < it[2], (s, it)
    assert all(g < j for g, j in zip(iters["gauss_seidel"], iters["jacobi"]))


def test_adaptive_subdivision_refines_only_where_light_changes():
    p = analytic.cornell_patches(max_edge=0.6)
    F = form_factors.form_factors(p, visibility.visibility_numpy(p))
    B = rad_solvers.solve_direct(F, p.rho, p.emission).B
    mask = rad_subdivision.refine_mask(p, rad_solvers.irradiance(F, B), threshold=0.3)
    assert 0 < mask.sum() < len(p)
    # the patches next to the light change fastest; a uniform white wall far from it does not refine entirely
    H = rad_solvers.irradiance(F, B) @ [0.2126, 0.7152, 0.0722]
    assert H[mask].std() > 0
    new, parent = rad_subdivision.split(p, mask)
    assert len(new) == len(p) + 3 * mask.sum()
    assert np.allclose(np.bincount(parent, weights=new.area, minlength=len(p)), p.area)


def test_split_preserves_area_and_triangles():
    m = [{"name": "t", "vertices": np.array([(0, 0, 0), (2, 0, 0), (0, 1, 0)]), "faces": [(0, 1, 2)]}]
    p = rad_patches.patches_from_meshes(m)
    q = rad_subdivision.subdivide_to_size(p, 0.3)
    assert q.is_tri.all() and q.area.sum() == pytest.approx(1.0)
    assert rad_patches.longest_edge(q.corners).max() <= 0.3


def test_atlas_round_trip_and_vertex_average():
    p = analytic.cornell_patches(max_edge=1.0)
    values = np.random.default_rng(0).random((len(p), 3))
    atlas = rad_atlas.make_atlas(len(p), cell=4, gutter=2)
    img = rad_atlas.paint_atlas(atlas, values, p.is_tri)
    assert np.allclose(rad_atlas.atlas_means(atlas, img[..., :3], p.is_tri), values, atol=1e-6)
    uv = rad_atlas.atlas_uvs(atlas, p.is_tri)
    assert uv.min() >= 0 and uv.max() <= 1
    corner, pos, idx = rad_atlas.vertex_average(p, np.ones((len(p), 3)) * 2.0)
    assert np.allclose(corner, 2.0) and np.allclose(pos[idx], p.corners)


def test_bad_inputs():
    with pytest.raises(InputError):
        rad_patches.patches_from_meshes([])
    with pytest.raises(InputError, match="rho"):
        rad_patches.patches_from_meshes([{"vertices": np.eye(3), "faces": [(0, 1, 2)], "rho": 1.0}])
    with pytest.raises(InputError, match="emits"):
        rad_solvers.solve_jacobi(np.zeros((2, 2)), np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(InputError, match="solver"):
        rad_solvers.solve(np.zeros((1, 1)), np.zeros((1, 3)), np.ones((1, 3)), np.ones(1), "magic")


def test_ceiling_over_a_lamp_edge_is_split_at_its_rim():
    """A ceiling patch (0..0.25 m, facing down, z = 2) whose edge lies over the edge of a lamp (−0.25..0.25,
    facing up, z = 1.98): at the texel centres (≥ 3 cm inside the edge) the lamp fills nearly the whole
    hemisphere, at its rim only half of it (a half-plane 2 cm below: F = ½), so the direct light varies by
    about half its mean and the patch must be split; a patch 0.5 m beyond the lamp's edge is not."""
    lamp = [(-0.25, -0.25, 1.98), (0.25, -0.25, 1.98), (0.25, 0.25, 1.98), (-0.25, 0.25, 1.98)]
    over = [(0, 0, 2.0), (0, 0.25, 2.0), (0.25, 0.25, 2.0), (0.25, 0, 2.0)]
    far = [(0.75, 0, 2.0), (0.75, 0.25, 2.0), (1.0, 0.25, 2.0), (1.0, 0, 2.0)]
    m = [{"name": n, "vertices": np.array(v), "faces": [(0, 1, 2, 3)], "rho": 0.7, "emission": e}
         for n, v, e in (("lamp", lamp, 10.0), ("over", over, 0.0), ("far", far, 0.0))]
    p = rad_patches.patches_from_meshes(m)
    pts, _ = rad_atlas.texel_points(p, 4)
    inner = form_factors.pointwise_form_factors(pts[1], np.repeat(p.normal[1:2], 16, 0), np.repeat(p.corners[:1], 16, 0))
    rim = form_factors.pointwise_form_factors(rad_subdivision.rim_points(p)[1], np.repeat(p.normal[1:2], 8, 0),
                                   np.repeat(p.corners[:1], 8, 0))
    def corner(a, b, h=0.02):       # point h above a corner of an a × b rectangle parallel to it
        A, B = np.hypot(a, h), np.hypot(b, h)
        return (a / A * np.arctan(b / A) + b / B * np.arctan(a / B)) / (2 * np.pi)
    x = 0.25 - rad_subdivision.RIM_INSET * 0.125           # the corner rim point over the lamp's corner, pulled inside
    exact = corner(0.25 + x, 0.25 + x) + 2 * corner(0.25 + x, 0.25 - x) + corner(0.25 - x, 0.25 - x)
    assert rim.min() == pytest.approx(exact, rel=1e-6) and exact < 0.35 and inner.min() > 0.85
    mask = rad_subdivision.emitter_refine_mask(p)
    assert mask[1] and not mask[2]


def _corner_rect(X, Y, h):
    """F from a point h below the corner of an X × Y rectangle parallel to it (Howell B-3), signed by the
    quadrant so that rectangles add and subtract (superposition)."""
    a, b = np.abs(X), np.abs(Y)
    A, B = np.hypot(a, h), np.hypot(b, h)
    return np.sign(X) * np.sign(Y) * (a / A * np.arctan(b / A) + b / B * np.arctan(a / B)) / (2 * np.pi)


def _square_over_floor(rho_floor=0.0, h=0.01, le=3.0):
    """A 0.2 m emitting square (L_e) facing down at height h over a 0.5 m floor patch reaching past its edge."""
    m = [{"name": "lamp", "vertices": np.array([(0, 0, h), (0, 0.2, h), (0.2, 0.2, h), (0.2, 0, h)]),
          "faces": [(0, 1, 2, 3)], "rho": 0.0, "emission": le},
         {"name": "floor", "vertices": np.array([(-0.1, -0.1, 0), (0.4, -0.1, 0), (0.4, 0.4, 0), (-0.1, 0.4, 0)]),
          "faces": [(0, 1, 2, 3)], "rho": rho_floor, "emission": 0.0}]
    return rad_patches.patches_from_meshes(m)


def test_texel_elements_tile_the_patch_and_sit_on_the_baked_texels():
    m = [{"name": "q", "vertices": np.array([(0, 0, 0), (1, 0, 0), (1.3, 1, 0), (0, 0.8, 0)]),
          "faces": [(0, 1, 2, 3), (0, 1, 2)]}]
    p = rad_patches.patches_from_meshes(m)
    for cell in (2, 4, 8):
        polys, pts, area, mask = rad_atlas.texel_elements(p, cell)
        assert area.sum(axis=1) == pytest.approx(p.area, rel=1e-12)           # a partition: areas add up
        tp, tm = rad_atlas.texel_points(p, cell)
        assert np.allclose(pts[tm], tp[tm], rtol=0, atol=1e-12) and (tm <= mask).all()  # every baked texel is a point
        assert mask[1].sum() == cell * (cell + 1) // 2                          # a triangle: squares + half squares
        _, nrm = rad_patches.polygon_area_normal(polys[mask])
        assert np.allclose(nrm, [0, 0, 1])                                       # wound as the patch
    values = np.random.default_rng(1).random((len(p), 16, 3))
    atlas = rad_atlas.make_atlas(len(p), cell=4)
    img = rad_atlas.paint_atlas(atlas, values, p.is_tri)
    got = rad_atlas.atlas_texels(atlas, img[..., :3], p.is_tri)
    _, tm = rad_atlas.texel_points(p, 4)
    assert np.allclose(got[tm], values[tm], atol=1e-6)                          # per-texel maps round-trip


@pytest.mark.parametrize("h", [0.001, 0.01])
def test_texel_gather_matches_point_irradiance_under_a_square(h):
    """Direct light only (a black floor): H(x) = π L_e F(dA_x -> square) at every texel, the closed form of a
    parallel rectangle by superposition of corner rectangles, down to a millimetre gap where the field
    steps at the square's outline within a texel's size. The lamp's patches are fine (8 x 8 elements) at
    1 mm (closer to the floor than its 4 x 4 elements are wide), not at 1 cm."""
    le = 3.0
    p = _square_over_floor(0.0, h, le)
    p = rad_subdivision.subdivide_to_size(p, 0.126)            # floor in 4 x 4 patches, lamp 2 x 2
    F = form_factors.form_factors(p)
    B = p.emission                                             # E = π L_e (patches_from_meshes)
    near = visibility.near_candidate_pairs(p)
    fine = gather.fine_patches(p, *near, 4)
    assert fine.sum() == (4 if h < 0.1 / 4 else 0) and not fine[p.owner == 1].any()
    nf = gather.NearField(p, *near, 4, fine=fine)
    g = gather.near_field_gather(p, F, B, nf)
    floor = p.owner == 1
    pts, mask = rad_atlas.texel_points(p, 4)
    x, y = pts[floor][..., 0], pts[floor][..., 1]
    exact = np.pi * le * (_corner_rect(0.2 - x, 0.2 - y, h) - _corner_rect(-x, 0.2 - y, h)
                          - _corner_rect(0.2 - x, -y, h) + _corner_rect(-x, -y, h))
    got = g.H[floor][..., 0]
    assert g.converged and exact.max() > 0.95 * np.pi * le and exact.min() < 1e-3 * np.pi * le
    # texels of patches near every lamp patch: exact up to K's float32 storage; the others take the far
    # lamp patches' light from F_ij (the patch centre's form factor), within the near criterion's error
    lamp = np.flatnonzero(p.owner == 0)
    pairs = set(zip(*near))
    all_near = np.array([all((i, j) in pairs for j in lamp) for i in np.flatnonzero(floor)])
    ok = mask[floor] & all_near[:, None]
    assert ok.sum() >= 32 and exact[ok].max() > 0.95 * np.pi * le
    assert np.allclose(got[ok], exact[ok], rtol=1e-6, atol=1e-9)
    assert np.allclose(got[mask[floor]], exact[mask[floor]], rtol=0, atol=1e-3 * np.pi * le)
    assert F.sum() == pytest.approx(form_factors.form_factors(p).sum())       # F is given back unchanged


def test_texel_gather_without_near_pairs_is_the_patch_solution():
    p = _square_over_floor(0.5, 1.0)
    F = form_factors.form_factors(p)
    B = rad_solvers.solve_jacobi(F, p.rho, p.emission, tol=1e-12).B
    none = np.zeros(0, int)
    g = gather.near_field_gather(p, F, B, gather.NearField(p, none, none, 4), tol=1e-12)
    assert np.allclose(g.patch_mean(), F @ B, rtol=1e-9) and np.allclose(g.B[g.mask], np.repeat(B, 16, 0), rtol=1e-9)


def test_texel_gather_of_a_closed_room_is_e_over_one_minus_rho_everywhere():
    """Every face of a closed cube emits E and reflects ρ: B = E / (1 − ρ) at every element when each
    element's form factors sum to 1. The cube of side 2 in 2 x 2 patches a face: every pair is near, so each
    element's row is an exact sum of point-to-polygon form factors over the other five faces (the float32
    of K aside)."""
    p = cube(2, rho=0.5, le=1.0)
    near = visibility.near_candidate_pairs(p)
    assert len(near[0]) == len(p) * (len(p) - 4)                  # every non-coplanar pair
    F = form_factors.form_factors(p)
    B = rad_solvers.solve_jacobi(F, p.rho, p.emission, tol=1e-10).B
    want = np.pi * 1.0 / (1 - 0.5)
    g = gather.near_field_gather(p, F, B, gather.NearField(p, *near, 4), tol=1e-9)
    assert g.converged and np.allclose(g.B[g.mask], want, rtol=1e-6)
    assert np.allclose(g.H[g.mask], want, rtol=1e-6)                 # H = (B − E) / ρ


def _warped_room():
    """The Cornell box with its right wall warped (one corner 6 mm out of plane, as the published box's red
    wall): a face the occluders take patch by patch."""
    meshes = analytic.cornell_box()
    for m in meshes:
        if m["name"] == "Right":
            m["vertices"] = np.array(m["vertices"], float)
            m["vertices"][np.argmax(m["vertices"].sum(axis=1))] += (0.006, 0, 0)
    return rad_patches.patches_from_meshes(meshes)


@pytest.mark.parametrize("warped", [False, True])
def test_face_visibility_equals_brute_force_rays_pair_by_pair(warped):
    base = _warped_room() if warped else rad_patches.patches_from_meshes(analytic.cornell_box())
    p = rad_subdivision.subdivide_to_size(base, 0.6)
    occ = visibility.occluders(base, p)
    # a planar face blocks as one polygon; the warped wall's patches block as their triangles (2 a quad)
    wall = np.array([p.names[o] == "Right" for o in p.owner])
    assert len(occ) == len(base) - 1 + (2 * wall.sum() if warped else 1)
    V = visibility.visibility_faces(p, occ, offset=1e-6, leaf=16)       # small clusters: every classification
    Vn = visibility.visibility_numpy(p)                                  # rays against every patch triangle
    assert np.array_equal(V, V.T) and 0 < V.sum() < V.size
    assert np.array_equal(V, Vn)
    # the per-point callback (near field, emitter split) says the same on every candidate pair
    i, j = visibility.candidate_pairs(p)
    vis = visibility.visible_faces(p, occ, offset=1e-6)(p.center[i], p.normal[i], j)
    assert np.array_equal(vis > 0.5, V[i, j])


def test_visible_pair_form_factors_equal_the_full_computation_and_reciprocity_is_closer():
    base = rad_patches.patches_from_meshes(analytic.cornell_box())
    p = rad_subdivision.subdivide_to_size(base, 0.5)
    p, _ = rad_subdivision.split(p, np.arange(len(p)) % 3 == 0)     # unequal neighbours: reciprocity matters
    V = visibility.visibility_faces(p, visibility.occluders(base, p))
    full = form_factors.form_factors(p, V)
    assert np.array_equal(form_factors.visible_form_factors(p, V, reciprocal=False), full)
    F = form_factors.visible_form_factors(p, V)
    a = p.area[:, None]
    assert np.allclose(F * a, (F * a).T, rtol=1e-12, atol=0)
    small = a < a.T                                                    # receiver the smaller of the pair
    assert np.array_equal(F[small & V], full[small & V]) and not F[~V].any()
    # against the patch-to-patch integral (6 x 6 points over the receiver): closer than every ordered pair
    # from its receiver's centre, the larger patch's centre rule error replaced by the smaller's (measured RMS
    # 6.8e-4 against 7.5e-4; the near pairs, which the texel gather replaces, dominate both)
    ref = form_factors.form_factors(p, V, quadrature=6)
    err_full, err_rec = np.sqrt(np.mean((full - ref) ** 2)), np.sqrt(np.mean((F - ref) ** 2))
    assert err_rec < err_full, (err_rec, err_full)
    assert np.abs(F - ref).max() <= np.abs(full - ref).max()


def test_float32_form_factors_still_solve_the_closed_enclosure():
    """F stored as float32 (solve_scene's): the closed cube's B = π L_e / (1 − ρ) within float32's rounding
    (relative 6e-8 a product, about 1e-6 after the sweeps), by every solver."""
    rho, le = 0.6, 2.0
    p = cube(3, rho=rho, le=le)
    V = visibility.visibility_faces(p, visibility.occluders(p))
    assert V.sum() == len(p) * (len(p) - len(p) // 6)        # a convex room: every patch off its own face
    F = form_factors.visible_form_factors(p, V, reciprocal=False, dtype=np.float32)
    assert F.dtype == np.float32
    for solver in rad_solvers.SOLVERS:
        sol = rad_solvers.solve(F, p.rho, p.emission, p.area, solver, tol=1e-6)
        assert sol.converged and np.allclose(sol.B, np.pi * le / (1 - rho), rtol=2e-5), solver


def test_near_candidate_pairs_are_the_near_pairs_of_every_candidate():
    """The cluster search finds exactly the near pairs of the brute-force candidate list (patches from 1 mm
    to 25 cm: the split near the light)."""
    base = rad_patches.patches_from_meshes(analytic.cornell_box())
    p = rad_subdivision.subdivide_to_size(base, 0.25)
    for _ in range(3):
        p, _ = rad_subdivision.split(p, p.emission.any(axis=1) | (np.arange(len(p)) % 7 == 0))
    want = form_factors.near_pairs(p, *visibility.candidate_pairs(p))
    got = visibility.near_candidate_pairs(p, leaf=16)
    assert len(got[0]) == len(set(zip(*got))) > len(p)
    assert set(zip(*got)) == set(zip(*want))


def test_a_wall_just_beside_a_ray_origin_still_blocks_it():
    """A wall standing on the floor 0.03 mm beside a floor patch's centre: the ray from that centre to the
    ceiling beyond the wall crosses it 0.07 mm above the floor, inside the wall (Blender's BVH ray counts a hit
    at its origin and ignores one only within 2 offsets of its target): blocked; the ceiling on the
    patch's own side stays visible."""
    x0 = 0.375 + 3e-5
    meshes = [{"name": "floor", "vertices": np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float),
               "faces": [(0, 1, 2, 3)], "rho": 0.5, "emission": 1.0},
              {"name": "ceiling", "vertices": np.array([(0, 0, 1), (0, 1, 1), (1, 1, 1), (1, 0, 1)], float),
               "faces": [(0, 1, 2, 3)], "rho": 0.5, "emission": 0.0},
              {"name": "wall", "vertices": np.array([(x0, 0, 0), (x0, 0, 0.5), (x0, 1, 0.5), (x0, 1, 0)], float),
               "faces": [(0, 1, 2, 3)], "rho": 0.5, "emission": 0.0}]
    base = rad_patches.patches_from_meshes(meshes)
    p = rad_subdivision.subdivide_to_size(base, 0.25)
    V = visibility.visibility_faces(p, visibility.occluders(base, p))
    floor, ceiling = p.owner == 0, p.owner == 1
    y = 0.375
    src = np.flatnonzero(floor & np.isclose(p.center[:, 0], 0.375) & np.isclose(p.center[:, 1], y))
    beyond = np.flatnonzero(ceiling & np.isclose(p.center[:, 0], 0.875) & np.isclose(p.center[:, 1], y))
    near = np.flatnonzero(ceiling & np.isclose(p.center[:, 0], 0.125) & np.isclose(p.center[:, 1], y))
    assert len(src) == len(beyond) == len(near) == 1
    assert src[0] < beyond[0]                              # the ray starts at the floor patch
    assert not V[src[0], beyond[0]] and not V[beyond[0], src[0]]
    assert V[src[0], near[0]]
