"""BVH4 builder and memory image (docs/datapath.md#quadbox, #bvh4-image): structural invariants read
back from the image."""

import numpy as np
import pytest

from support import meshes
from support.images import check_bvh
from driver import QUADBOX, TRIANGLE, backend, prepare_rays
from driver import bvh4
from driver.bvh import build as bvh_build
from driver.bvh import collapse as bvh_collapse
from driver.bvh import image, reference
from driver.bvh4 import NO_CHILD, TRI_TYPE, build



MESHES = {
    "soup1": lambda: meshes.soup(1),
    "soup2": lambda: meshes.soup(2, seed=1),
    "soup500": lambda: meshes.soup(500, seed=2),
    "room": meshes.box_room,
    "sphere": meshes.icosphere,
    "degenerate": meshes.degenerate,
}


OPTIONS = [{"builder": "fast", "collapse": "sah"}, {"builder": "fast", "collapse": "greedy"},
           {"builder": "numpy", "collapse": "sah"}, {"builder": "fast", "fill": 40},
           {"builder": "fast", "fill": 1 << 30}]


@pytest.mark.parametrize("opts", OPTIONS, ids=lambda o: "-".join(map(str, o.values())))
@pytest.mark.parametrize("name", MESHES)
def test_invariants(name, opts):
    bvh = build(MESHES[name](), **opts)
    check_bvh(bvh)


def random_meshes():
    """Soups of several sizes and densities, a clustered soup, the sphere and the room."""
    rng = np.random.default_rng(3)
    out = [meshes.soup(n, seed=s) for n, s in ((5, 1), (37, 2), (300, 3), (2000, 4))]
    centers = rng.uniform(-10, 10, (8, 3))[rng.integers(0, 8, 400)]
    out.append((centers[:, None, :] + rng.normal(0, 0.3, (400, 3, 3))).astype(np.float32))
    return out + [meshes.icosphere(), meshes.box_room()]


def test_sah_collapse_never_worse_than_greedy():
    """The DP collapse is optimal over the binary tree, so its SAH never exceeds the greedy one's
    (computed from the same stored boxes; 1e-12: summation order)."""
    for tris in random_meshes():
        sah = build(tris, collapse="sah").stats
        greedy = build(tris, collapse="greedy").stats
        assert sah["sah_cost"] <= greedy["sah_cost"] * (1 + 1e-12)
        assert sah["box_nodes"] <= greedy["box_nodes"] * 1.05


def _leaf_counts(left, right):
    """Triangles under each binary node (children are numbered after their parents)."""
    cnt = np.ones(len(left), np.int64)
    for n in range(len(left) - 1, -1, -1):
        if left[n] >= 0:
            cnt[n] = cnt[left[n]] + cnt[right[n]]
    return cnt


@pytest.mark.parametrize("fill", [8, 40, 1 << 30])
def test_fillable_splits_keep_the_rule(fill):
    """Every node of at most ``fill`` triangles splits as the rule says (n = 1 mod 3 into two of
    2 mod 3, n = 2 mod 3 into two of 1 mod 3, n = 0 mod 3 into 1 + 2), larger nodes freely; with
    no limit the tree then reaches the least possible number of box nodes, ceil((n - 1) / 3),
    up to the non-full nodes the SAH collapse prefers."""
    for tris in random_meshes():
        tris = np.asarray(tris, np.float32)
        left, right = bvh_build.build_binary(tris, 16, None, fill)[:2]
        cnt = _leaf_counts(left, right)
        inner = np.flatnonzero(left >= 0)
        n, nl = cnt[inner], cnt[left[inner]]
        small = n <= fill
        assert small.any()
        want = np.where(n % 3 == 1, nl % 3 == 2, np.where(n % 3 == 2, nl % 3 == 1, nl % 3 != 0))
        assert want[small].all()
    tris = meshes.soup(2000, seed=4)
    full = build(tris, fill=1 << 30).stats
    plain = build(tris).stats
    least = -(-(len(tris) - 1) // 3)
    assert least <= full["box_nodes"] < plain["box_nodes"]
    assert full["box_nodes"] <= 1.1 * least
    assert full["fill"] == 1 << 30 and plain["fill"] == 0


def test_fill_zero_is_the_plain_tree():
    """``fill=0`` is the plain SAH build, byte for byte."""
    for tris in random_meshes()[:4]:
        assert np.array_equal(build(tris).image, build(tris, fill=0).image)


@pytest.mark.parametrize("fill", [-1, 2.5, True, "8"])
def test_bad_fill(fill):
    with pytest.raises(ValueError, match="fill must be an integer"):
        build(meshes.soup(3), fill=fill)


def test_fill_needs_the_fast_builder():
    with pytest.raises(ValueError, match="fast builder"):
        build(meshes.soup(30), fill=8, builder="numpy")


def test_fast_builder_same_or_better_sah_than_numpy():
    """The numba builder follows the numpy builder's rules, so its trees are as good (in fact
    the same tree, numbered in another order)."""
    for tris in random_meshes():
        for collapse in ("greedy", "sah"):
            fast = build(tris, builder="fast", collapse=collapse).stats
            ref = build(tris, builder="numpy", collapse=collapse).stats
            assert fast["sah_cost"] <= ref["sah_cost"] * (1 + 1e-12)
            assert fast["box_nodes"] == ref["box_nodes"]


def _subtrees(left, right, prim, lo, hi):
    """{sorted primitive ids under a binary node: its box} (numbering-independent)."""
    under = [None] * len(left)
    for n in range(len(left) - 1, -1, -1):              # children are numbered after parents
        under[n] = (int(prim[n]),) if left[n] < 0 else under[left[n]] + under[right[n]]
    return {tuple(sorted(u)): tuple(np.r_[lo[n], hi[n]].tolist()) for n, u in enumerate(under)}


def test_fast_binary_tree_is_the_numpy_tree(monkeypatch):
    """The numba kernels (binned nodes, the small-subtree sweep that sorts once, the threaded
    top) make the numpy reference's tree: the same primitive sets under the same boxes, on
    meshes with equal centroids (ties keep list order) too."""
    rng = np.random.default_rng(11)
    dup = np.repeat(meshes.soup(40, seed=5), 3, axis=0)[rng.permutation(120)]
    monkeypatch.setattr(bvh_build, "PARALLEL_MIN", 100)     # the threaded top from 100 triangles
    for tris in random_meshes() + [dup]:
        tris = np.asarray(tris, np.float32)
        fast = bvh_build.build_binary(tris, 16)
        ref = reference._build_binary(*reference._prim_boxes(tris), 16)
        assert _subtrees(*fast) == _subtrees(*ref)


def _brute_force_collapse(left, right, area):
    """Least sum of slot areas over every choice of kept interior nodes (root always kept) in
    which every kept node has at most 4 children in the contracted tree."""
    interior = [i for i in range(1, len(left)) if left[i] >= 0]
    best = np.inf
    for mask in range(1 << len(interior)):
        kept = {0} | {n for b, n in enumerate(interior) if mask >> b & 1}

        def slots(n):                                  # children of kept n in the wide tree
            out = []
            for c in (left[n], right[n]):
                out += [c] if c in kept or left[c] < 0 else slots(c)
            return out
        if all(len(slots(n)) <= 4 for n in kept):
            best = min(best, sum(area[n] for n in kept if n) + area[left < 0].sum())
    return best


@pytest.mark.parametrize("n,seed", [(5, 0), (9, 1), (12, 2), (14, 3)])
def test_sah_collapse_is_optimal(n, seed):
    tris = meshes.soup(n, seed=seed)
    left, right, _, lo, hi = bvh_build.build_binary(tris, 16)
    area = bvh_build.grow_boxes(lo, hi, 1e-3)
    levels = bvh_collapse.collapse_sah(left, right, area)
    slots = np.concatenate(levels)
    dp = area[slots[slots >= 0]].sum()
    assert dp == pytest.approx(_brute_force_collapse(left, right, area), rel=1e-12)


def test_progress_bar_on_stderr(capsys):
    build(meshes.soup(50), progress=True)
    assert "BVH build" in capsys.readouterr().err
    build(meshes.soup(50))                                  # small input: no bar by default
    assert "BVH build" not in capsys.readouterr().err


def test_threaded_build_is_deterministic(monkeypatch):
    """Above PARALLEL_MIN the subtrees are built on threads; the tree does not depend on it."""
    tris = meshes.soup(3000, seed=9)
    one = build(tris)
    monkeypatch.setattr(bvh_build, "PARALLEL_MIN", 100)
    threaded = build(tris)
    assert np.array_equal(one.image, threaded.image)
    for a, b in zip(bvh_build.build_binary(tris, 16, threads=1),
                    bvh_build.build_binary(tris, 16, threads=3)):
        assert np.array_equal(a, b)


def test_single_triangle_has_a_root_box():
    bvh = build(meshes.soup(1))
    children, _ = bvh.box_nodes([bvh.root])
    assert bvh.stats["box_nodes"] == 1 and bvh.stats["depth"] == 1
    assert (children[0, 1:] == NO_CHILD).all() and bvh.node_type(children[0, :1])[0] == TRI_TYPE
    assert len(bvh.image) == 128 + 64


def test_coincident_centroids_and_trimesh_input():
    tri = meshes.soup(1)
    bvh = build(np.repeat(tri, 9, axis=0))                  # 9 identical triangles
    check_bvh(bvh)
    m = meshes.bunny().copy()
    m.update_faces(np.arange(200))
    bvh = build(m)
    assert np.array_equal(bvh.triangles, np.asarray(m.vertices, np.float32)[m.faces])
    check_bvh(bvh)


def test_sah_beats_a_random_tree():
    """SAH cost of 500 soup triangles stays far below a tree built in random order (whose nodes
    are about as large as the root: several hundred ops); ~16 here."""
    assert build(meshes.soup(500, seed=2)).stats["sah_cost"] < 60


def test_bunny():
    build(meshes.soup(3))            # compile/load the numba kernels outside the timed build
    bvh = build(meshes.bunny())
    s = bvh.stats
    print(f"\nbunny: {s}")
    assert s["tri_nodes"] == 99_785
    assert s["build_s"] < 4.0       # ~0.2 s here (`rayflex bench --bvh`); a loose bound only
    check_bvh(bvh)


@pytest.mark.parametrize("bad", [
    np.zeros((0, 3, 3)), np.zeros((4, 3)), np.zeros((4, 3, 2)), np.zeros((2, 9)), [[1, 2, 3]],
    np.array([[[0, 0, 0], [1, 0, 0], [0, np.nan, 0]]]),
    np.array([[[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]]),
    np.array([[[0, 0, 0], [1, 0, 0], [0, 1e39, 0]]]),        # overflows float32
    "not triangles",
], ids=["empty", "n3", "n32", "n9", "ragged", "nan", "inf", "f32overflow", "str"])
def test_bad_input(bad):
    with pytest.raises(ValueError):
        build(bad)


def test_bad_trimesh_input():
    import trimesh
    for mesh in (trimesh.Trimesh(),
                 trimesh.Trimesh([[0, 0, 0], [1e39, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False),
                 trimesh.Trimesh(np.zeros((3, 3)), [[0, 1, 5]], process=False)):
        with pytest.raises(ValueError):
            build(mesh)


def test_bad_bins():
    with pytest.raises(ValueError):
        build(meshes.soup(3), bins=1)


@pytest.mark.parametrize("opts", [{"builder": "embree"}, {"collapse": "best"}])
def test_bad_options(opts):
    with pytest.raises(ValueError, match="must be one of"):
        build(meshes.soup(3), **opts)


# ---- the datapath and the stored boxes ---------------------------------------------------------

def _axis_dirs():
    d = []
    for ax in range(3):
        for s in (1.0, -1.0, 0.5):
            v = [0.0, 0.0, 0.0]
            v[ax] = s
            d.append(v)
    d += [[-0.0, -0.0, 1.0], [-0.0, 1.0, -0.0], [1.0, -0.0, 0.0], [0.0, -1.0, -0.0]]
    return np.array(d, np.float32)


def test_stored_boxes_are_the_grown_float32_bounds():
    """``grow_boxes`` applies the module docstring's rule in place, ``nextafter(float32(min -
    pad), -inf)`` and ``nextafter(float32(max + pad), +inf)``, bit for bit (zeros, tiny, huge and
    overflowing bounds included), to float32 and float64 bounds alike, and returns the half
    areas of the grown boxes."""
    rng = np.random.default_rng(8)
    lo = np.r_[rng.normal(0, 100, (500, 3)), [[0.0, -0.0, 1e-45], [3e38, -3e38, 1e39]]]
    hi = lo + np.r_[rng.uniform(0, 10, (500, 3)), np.zeros((2, 3))]
    with np.errstate(over="ignore"):
        lo32, hi32 = lo.astype(np.float32), hi.astype(np.float32)
    for pad in (0.0, 1e-3):
        with np.errstate(over="ignore"):
            want_lo = np.nextafter((lo32 - pad).astype(np.float32), np.float32(-np.inf))
            want_hi = np.nextafter((hi32 + pad).astype(np.float32), np.float32(np.inf))
        with np.errstate(invalid="ignore", over="ignore"):
            want_area = image._half_area(want_lo.astype(np.float64), want_hi)
        for dtype in (np.float32, np.float64):
            glo, ghi = lo32.astype(dtype), hi32.astype(dtype)
            area = bvh_build.grow_boxes(glo, ghi, pad)
            assert np.array_equal(glo.astype(np.float32).view(np.uint32), want_lo.view(np.uint32))
            assert np.array_equal(ghi.astype(np.float32).view(np.uint32), want_hi.view(np.uint32))
            assert np.array_equal(area, want_area, equal_nan=True)


def test_unused_slot_never_hit():
    """An unused slot's +inf box misses for every ray, axis-parallel and signed zeros included."""
    rng = np.random.default_rng(5)
    d = np.concatenate([rng.normal(size=(400, 3)), _axis_dirs()]).astype(np.float32)
    o = rng.uniform(-1e3, 1e3, (len(d), 3)).astype(np.float32)
    o[:20] = 0
    req = prepare_rays(o, d)
    req["opcode"] = QUADBOX
    req["box"] = np.inf
    rsp = backend("golden").run(req)
    assert not rsp["box_hit"].any()
    assert np.isposinf(rsp["box_tmin"]).all()


@pytest.mark.parametrize("name,dist", [("degenerate", 2), ("degenerate", 64), ("room", 2),
                                       ("room", 64), ("soup500", 64)])
def test_boxes_conservative_on_the_datapath(name, dist):
    """Whenever the golden TRIANGLE op hits a triangle, the golden QUADBOX op hits the box its
    parent stores for it (and, slab results being monotone in the box, every ancestor's box).
    Rays aim at random points of triangles from origins up to ``dist`` * S from the world origin
    (S = largest |coordinate|; bvh4's documented range is ~100 S), and graze flat triangles
    along their plane from 0.5 S away."""
    tris = MESHES[name]()
    bvh = build(tris)
    leaf = check_bvh(bvh)
    rng = np.random.default_rng(11)
    n = len(tris)
    ti = np.repeat(np.arange(n), 40)
    w = rng.dirichlet([1, 1, 1], len(ti)).astype(np.float32)
    target = np.einsum("ij,ijk->ik", w, tris[ti])
    scale = np.abs(tris).max()
    u = rng.normal(size=target.shape)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    o = u * scale * rng.uniform(0.01, dist, (len(ti), 1))
    o[1::4] = u[1::4] * scale * dist                        # at the far end of the range
    o[::4] = target[::4] + 0.5 * scale * np.eye(3)[ti[::4] % 3]
    o = o.astype(np.float32)
    d = target - o
    d[d == 0] = 1e-3
    req = prepare_rays(o, d)
    req["opcode"] = TRIANGLE
    req["tri"] = tris[ti]
    gold = backend("golden")
    hit = gold.run(req)["tri_hit"].astype(bool)
    assert hit.sum() > len(ti) // 10
    req = req[hit]
    req["opcode"] = QUADBOX
    req["box"] = np.inf
    req["box"][:, 0] = np.array([leaf[i] for i in ti[hit]])
    rsp = gold.run(req)
    assert rsp["box_hit"][:, 0].all()


# ---- benchmark helpers -----------------------------------------------------------------------

def test_instanced_bunnies():
    from driver.studies.bvh import BUNNY_TRIANGLES, instanced_bunnies
    x = instanced_bunnies(2, seed=1)
    assert x.shape == (2 * BUNNY_TRIANGLES, 3, 3) and x.dtype == np.float32
    assert np.array_equal(x, instanced_bunnies(2, seed=1))
    assert not np.array_equal(x, instanced_bunnies(2, seed=2))
    a, b = x[:BUNNY_TRIANGLES], x[BUNNY_TRIANGLES:]
    assert a[..., 0].max() < b[..., 0].min(), "copies side by side, not overlapping"
    assert a[..., 2].min() == pytest.approx(0, abs=1e-3) and b[..., 2].min() == pytest.approx(0, abs=1e-3)
    with pytest.raises(ValueError):
        instanced_bunnies(0)


def test_bvh_bench_command_checks_before_building(tmp_path, capsys):
    from driver.cli import main as cli_main

    def main(argv):                          # the study's command: rayflex study bvh
        return cli_main(["study", "bvh", *argv])
    assert main(["--counts", "-1"]) == 2
    assert main(["--counts", "0", "--json", str(tmp_path / "none" / "b.json")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and all(e.startswith("rayflex: error: ") for e in err)
    assert not (tmp_path / "none").exists()


def test_bvh_bench_dict(tmp_path):
    from driver.studies.bvh import BUNNY_TRIANGLES, FORMATS, build_table, bvh_bench
    r = bvh_bench(counts=(0,), size=32, progress=False, fills=(0, 1 << 30),
                  plot=tmp_path / "fills.png")
    assert [b["format"] for b in r["builds"]] == list(FORMATS)
    for b in r["builds"]:
        assert b["triangles"] == BUNNY_TRIANGLES and b["build_s"] > 0
        assert b["peak_rss_mb"] >= b["rss_before_mb"] > 0
        assert ("vs_box32_build_s" in b) == (b["format"] != "box32")
    size = {b["format"]: b["bytes_per_triangle"] for b in r["builds"]}
    assert size["q8g"] < size["q8"] < 0.5 * size["box32"]
    table = build_table(r).splitlines()               # the docs/compressed.md table
    assert len(table) == 3 and table[2].startswith(f"| bunny, {BUNNY_TRIANGLES:,} triangles |")
    cpu = {b["format"]: b["build_cpu_s"] for b in r["builds"]}
    assert f"| {cpu['q8g'] / cpu['box32']:.2f} (" in table[2]
    q = r["quality"]
    assert q["sah"]["sah_cost"] <= q["greedy"]["sah_cost"]
    assert q["sah"]["box_nodes"] < q["greedy"]["box_nodes"]
    assert q["same_hits"]["hit_mismatch"] == 0 and q["same_hits"]["hits"] > 0
    assert q["same_hits"]["prim_mismatch"] == q["same_hits"]["prim_mismatch_same_t"]
    f = q["fills"]
    plain, full = f["rows"]
    assert plain["fill"] == 0 and plain["box_nodes"] == q["sah"]["box_nodes"]
    assert plain["ops_per_ray"] == q["sah"]["ops_per_ray"]
    assert full["box_nodes"] < plain["box_nodes"] and full["sah_cost"] > plain["sah_cost"]
    for row in f["rows"]:
        assert row["same_hits"]
        assert row["culled_ops_per_ray"] < row["ops_per_ray"]
        assert row["culled_box_ops_per_ray"] + row["stack_culls_per_ray"] == pytest.approx(
            row["box_ops_per_ray"], abs=2e-4)
    assert f["reference"]["box_nodes"] == 36_000 and f["reference"]["ops_per_ray"] == 5.9755
    assert f["reference"]["within"] == [
        {"fill": r["fill"], "cull_stack": cull} for r in f["rows"]
        for cull, key in ((False, "ops_per_ray"), (True, "culled_ops_per_ray"))
        if r["box_nodes"] <= 36_000 and r[key] <= 5.9755]
    assert (tmp_path / "fills.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_malformed_binary_tree_is_an_error_not_a_walk_without_end():
    """``check_tree`` (run on every build): the walks down the tree end because children are
    numbered after their parent, each node has one parent; a cycle or a shared child is
    refused."""
    left, right = np.array([1, -1, -1]), np.array([2, -1, -1])
    bvh_build.check_tree(left, right)
    for l, r in (([1, 0, -1], [2, 0, -1]),          # a cycle back to the root
                 ([1, -1, -1], [1, -1, -1]),        # one child twice, node 2 unreached
                 ([1, -1, -1], [-1, -1, -1])):      # an interior node with one child
        with pytest.raises(RuntimeError, match="malformed"):
            bvh_build.check_tree(np.array(l), np.array(r))
