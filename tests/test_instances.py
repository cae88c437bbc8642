"""Instances: the ray transform, the two-level image, instanced vs flattened hits, scenes."""

import numpy as np
import pytest
import trimesh
from PIL import Image

from driver.bvh.instances import _box_node, build_two_level, tlas_format
from driver import instances as instances_mod
from driver.instances import world_boxes
from driver.bvh4 import box_operands
from driver.instances import Instances, affine, transform_ray
from driver.core.wire import FLAG_DECODE_Q8
from driver.core.layout import (IMAGE_FORMATS, INSTANCE_BYTES, INSTANCE_NODE, INSTANCE_TYPE,
                                NO_CHILD, NODE_BYTES, Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, Q8_TYPE,
                                NodeRef, read_nodes)
from driver.tracer import trace as _trace
from support.meshes import reuse_glb


def trace(*args, backend="golden", **options):
    """``driver.tracer.trace`` on the golden model unless a test names a backend: these tests
    check the traversal, and every backend gives the same responses (tests/test_rtl.py)."""
    return _trace(*args, backend=backend, **options)

T_REL = 1e-5        # the transform's rounding: largest relative t difference allowed


def _rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return trimesh.transformations.quaternion_matrix(q)[:3, :3]


def random_instances(seed=0, k=14, mirror=True):
    """Instances of three meshes with random rotations, non-uniform scales, translations, a
    third of them mirrored."""
    rng = np.random.default_rng(seed)
    meshes = [trimesh.creation.icosphere(2).triangles, trimesh.creation.box().triangles,
              trimesh.creation.cone(0.6, 1.5, sections=9).triangles]
    mats = []
    for i in range(k):
        m = _rotation(rng) @ np.diag(rng.uniform(0.4, 2.0, 3))
        if mirror and i % 3 == 0:
            m = m @ np.diag([1.0, -1.0, 1.0])
        mats.append(np.hstack([m, rng.uniform(-6, 6, (3, 1))]))
    return Instances(meshes, rng.integers(0, 3, k), np.array(mats))


def random_rays(n, seed=1, spread=12.0):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-spread, spread, (n, 3)).astype(np.float32)
    target = rng.uniform(-6, 6, (n, 3))
    return o, (target - o).astype(np.float32)


def assert_same_hits(a, b, any_hit=False):
    """Instanced ``a`` vs flattened ``b``: the same rays hit; closest hits name the same triangle
    and their t differ by the transform's rounding only."""
    assert np.array_equal(a.hit, b.hit)
    both = a.hit & b.hit
    if not any_hit:
        assert np.array_equal(a.prim, b.prim)
    rel = np.abs(a.t[both].astype(np.float64) - b.t[both]) / np.abs(b.t[both])
    assert rel.max(initial=0) <= T_REL


# ---- the transform ------------------------------------------------------------------------------

def _scalar_transform(m, o, d):
    f = np.float32
    o2 = [((f(m[r][0]) * f(o[0]) + f(m[r][1]) * f(o[1])) + f(m[r][2]) * f(o[2])) + f(m[r][3])
          for r in range(3)]
    d2 = [(f(m[r][0]) * f(d[0]) + f(m[r][1]) * f(d[1])) + f(m[r][2]) * f(d[2]) for r in range(3)]
    return np.array(o2, np.float32), np.array(d2, np.float32)


def _same_bits(a, b):
    a, b = np.asarray(a, np.float32), np.asarray(b, np.float32)
    nan = np.isnan(a) & np.isnan(b)
    return bool(((a.view(np.uint32) == b.view(np.uint32)) | nan).all())


def test_transform_ray_equals_scalar_float32_reference():
    rng = np.random.default_rng(5)
    n = 400
    m = rng.normal(size=(n, 3, 4)).astype(np.float32)
    m[::7] *= np.float32(1e30)                       # huge: products overflow to inf
    m[1::7] *= np.float32(1e-30)                     # tiny: subnormal products
    m[2::7, 0] = 0.0                                 # singular rows
    m[3::7, :, 1] = -0.0
    m[4::7, 0, 0] = np.nan
    m[5::7] = m[5::7] * np.float32(-1)               # negative determinant
    o = rng.normal(size=(n, 3)).astype(np.float32) * np.float32(100)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    d[6::7] = 0.0
    with np.errstate(all="ignore"):
        o2, d2 = transform_ray(m, o, d)
        for i in range(n):
            ro, rd = _scalar_transform(m[i], o[i], d[i])
            assert _same_bits(o2[i], ro) and _same_bits(d2[i], rd), i
    # one matrix for every ray broadcasts
    o3, d3 = transform_ray(m[0], o, d)
    assert _same_bits(o3, transform_ray(np.broadcast_to(m[0], m.shape), o, d)[0])


# ---- the image ----------------------------------------------------------------------------------

def _tlas(bvh):
    """(pointers (n,), children (n, 4), decoded child boxes (n, 4, 6) float64) of a two-level
    image's TLAS box nodes, in image order."""
    node, size, typ = _box_node(tlas_format(bvh.format))
    nb = bvh.stats["tlas_box_nodes"]
    assert bvh.stats["tlas_bytes"] == size * nb and bvh.root == NodeRef.encode(0, typ)
    ptrs = NodeRef.encode(size * np.arange(nb), typ)
    children, boxes = box_operands(bvh.image.view("<u4"), ptrs)
    return ptrs, children, boxes.astype(np.float64)


def _instance_world_boxes(bvh, k):
    """(len(k), 2, 3) float64: the world box of instances ``k``, from their BLAS root's box."""
    inst = bvh.instances
    local = []
    for kk in k:
        children, cb = bvh.box_nodes(bvh.blas_root[[kk]])
        used = cb[0][children[0] != NO_CHILD].astype(np.float64)
        local.append(np.concatenate([used[:, :3].min(0), used[:, 3:].max(0)]))
    sub = Instances(inst.meshes, inst.mesh[k], inst.object_to_world[k])
    return world_boxes(sub, np.array(local)).astype(np.float64)


@pytest.mark.parametrize("fmt", IMAGE_FORMATS)
def test_two_level_image_invariants(fmt):
    """Every TLAS child pointer names a TLAS node (each once, parent pointers back) or an
    instance node (each instance once, intact); every decoded TLAS box contains the world boxes
    of all the instances below it; the BLASes are in ``fmt`` (q8g: with group leaves)."""
    inst = random_instances(3)
    bvh = build_two_level(inst, format=fmt)
    words = bvh.image.view("<u4")
    ptrs, child, boxes = _tlas(bvh)
    t_node, t_size, t_type = _box_node(tlas_format(fmt))
    assert NODE_BYTES[t_type] == t_size == (128 if fmt == "box32" else 64)
    used = child != NO_CHILD
    typ = NodeRef.type(child)
    assert np.isin(typ[used], (t_type, INSTANCE_TYPE)).all(), "TLAS children: TLAS or instance"
    inner = used & (typ == t_type)
    kids = NodeRef.offset(child[inner])
    assert (kids % t_size == 0).all() and (kids < bvh.stats["tlas_bytes"]).all()
    assert sorted(kids.tolist()) == list(range(t_size, bvh.stats["tlas_bytes"], t_size))
    parents = read_nodes(words, ptrs, t_node)["parent"]
    assert parents[0] == NO_CHILD
    assert np.array_equal(parents[kids // t_size], np.repeat(ptrs, 4).reshape(-1, 4)[inner])
    leaf = used & (typ == INSTANCE_TYPE)
    assert leaf.sum() == len(inst), "every instance is one TLAS leaf"
    offs = NodeRef.offset(child[leaf])
    inst_off = bvh.stats["tlas_bytes"]
    assert ((offs - inst_off) % INSTANCE_BYTES == 0).all()
    nodes = read_nodes(words, child[leaf], INSTANCE_NODE)
    k = nodes["instance"].astype(np.int64)
    assert sorted(k) == list(range(len(inst)))
    assert np.array_equal((offs - inst_off) // INSTANCE_BYTES, k), "instance nodes in order"
    # BLAS pointers: a box node of the image's BLAS region, one BLAS per (mesh, mirrored)
    offsets = {b["offset"] for b in bvh.blas}
    assert set(NodeRef.offset(nodes["blas"]).tolist()) <= offsets
    assert NodeRef.is_box(nodes["blas"]).all()
    assert np.array_equal(nodes["blas"], bvh.blas_root[k])
    blas_of = {b["offset"]: b for b in bvh.blas}
    for i, p in enumerate(bvh.blas_root):
        b = blas_of[int(NodeRef.offset(p))]
        assert b["mesh"] == inst.mesh[i] and b["mirrored"] == inst.mirrored[i]
        assert len(b["stats"]) and b["stats"]["format"] == fmt
    if fmt == "q8g":
        assert sum(b["stats"]["group_leaves"] for b in bvh.blas) > 0
    # the two matrices are inverses within float32 rounding
    assert np.array_equal(nodes["object_to_world"], inst.object_to_world[k])
    prod = affine(nodes["world_to_object"]) @ affine(nodes["object_to_world"])
    assert np.abs(prod - np.eye(4)).max() < 1e-5
    # every decoded TLAS box contains the world boxes of the instances below it
    world = _instance_world_boxes(bvh, np.arange(len(inst)))
    index = {int(p): r for r, p in enumerate(ptrs)}
    inst_at = {int(c): int(kk) for c, kk in zip(child[leaf], k)}

    def below(p):
        if int(p) in inst_at:
            return [inst_at[int(p)]]
        return [i for c in child[index[int(p)]] if c != NO_CHILD for i in below(c)]

    checked = 0
    for r, s in zip(*np.nonzero(used)):
        w = world[below(child[r, s])]
        assert (boxes[r, s, :3] <= w[:, 0]).all() and (boxes[r, s, 3:] >= w[:, 1]).all()
        checked += len(w)
    assert checked > len(inst)


def test_q8_tlas_nodes():
    """A q8 TLAS (under q8 BLASes): 64-byte q8 box nodes, half box32's per node, exponents in
    range, counts matching the used slots; the image's bytes are its three parts."""
    inst = random_instances(4, k=40)
    a, b = (build_two_level(inst, format=f) for f in ("box32", "q8"))
    assert a.stats["tlas_format"] == "box32" and b.stats["tlas_format"] == "q8"
    assert b.stats["tlas_bytes"] == 64 * b.stats["tlas_box_nodes"]
    assert a.stats["tlas_bytes"] == 128 * a.stats["tlas_box_nodes"]
    assert b.stats["tlas_bytes"] < a.stats["tlas_bytes"]
    assert b.stats["bytes"] == (b.stats["tlas_bytes"] + b.stats["instance_bytes"]
                                + b.stats["blas_bytes"])
    q = read_nodes(b.image.view("<u4"), _tlas(b)[0], Q8_NODE)
    exp = q["exp"][:, :3].view(np.int8)
    assert ((exp >= Q8_EXP_MIN) & (exp <= Q8_EXP_MAX)).all()
    count = q["exp"][:, 3] & 7
    assert ((count >= 1) & (count <= 4)).all()
    assert np.array_equal(count, (q["child"] != NO_CHILD).sum(1))


def _same_image_hits(a, b, any_hit=False):
    """Two two-level images of one scene (same transforms, same BLAS triangles): the same rays
    hit; closest hits at the same t bit for bit, the same primitive and instance except
    between triangles hit at exactly the same t."""
    assert np.array_equal(a.hit, b.hit)
    if any_hit:
        return
    assert np.array_equal(a.t.view(np.uint32), b.t.view(np.uint32))
    other = (a.prim != b.prim) | (a.instance != b.instance)
    assert other.sum() <= max(2, a.hit.sum() // 200), "ties only"


@pytest.mark.parametrize("backend", ["golden", "rtl"])
def test_q8_two_level_gives_the_box32_two_level_hits(backend):
    """A random scene graph (rotations, non-uniform scales, mirrors) as a q8 and a q8g two-level
    image (q8 TLAS): the hits of the box32 two-level image for closest-hit, any-hit and
    double-sided rays, with the q8 nodes (TLAS included) decoded on the host and, on a backend
    with the decode (``--config baseline-unified-q8``), sent as stored with DECODE_Q8."""
    import driver
    inst = random_instances(5)
    assert inst.mirrored.any()
    o, d = random_rays(1500, 13)
    ref = build_two_level(inst, format="box32")
    be = driver.backend(backend, compressed=True)
    for fmt in ("q8", "q8g"):
        bvh = build_two_level(inst, format=fmt)
        for kw in ({}, {"any_hit": True, "extent": 15.0}, {"double_sided": True}):
            a = trace(ref, o, d, backend=backend, **kw)
            host = trace(bvh, o, d, backend=backend, **kw)
            assert a.hit.sum() > 100 and a.stats["instance_ops"] > 0
            _same_image_hits(host, a, "any_hit" in kw)
            dec = trace(bvh, o, d, backend=be, record=not kw, **kw)
            _same_trace(dec, host)
            assert dec.stats["box_ops"] == host.stats["box_ops"]
        rec = dec.record if dec.record is not None else trace(bvh, o, d, backend=be,
                                                              record=True).record
        req = rec.requests()
        q8 = NodeRef.type(rec.ptr) == Q8_TYPE
        tlas = q8 & (NodeRef.offset(rec.ptr) < bvh.stats["tlas_bytes"])
        assert tlas.sum() >= 1500, "every ray starts at the q8 TLAS root"
        assert ((req["flags"][q8] & FLAG_DECODE_Q8) != 0).all()
        if backend == "rtl":
            from driver import rtunit
            assert rtunit.replay(rec, 32, 1, datapath="rtl").verified


@pytest.mark.parametrize("backend", ["golden", "rtl"])
def test_small_bunny_grid_q8_two_level_gives_the_box32_hits(backend):
    """The bunny grid's builder at a small size (6 instances of a sphere on the floor): the q8
    and q8g two-level images (q8 TLAS) hit as the box32 one, t bit for bit, on the golden model
    and on the RTL with the q8 decode."""
    import driver
    from driver.scenes.builtins import bunny_grid
    from driver.scenes.camera import Camera, primary_rays
    b = bunny_grid(lambda: trimesh.creation.icosphere(3).triangles, 6)
    o, d = primary_rays(Camera(**b.camera).validate(), 32, 32)
    a = trace(build_two_level(b.instances, format="box32"), o, d)
    assert a.hit.sum() > 100 and len(np.unique(a.instance[a.hit])) > 3
    be = driver.backend(backend, compressed=True)
    for fmt in ("q8", "q8g"):
        bvh = build_two_level(b.instances, format=fmt)
        host = trace(bvh, o, d)
        _same_image_hits(host, a)
        _same_trace(trace(bvh, o, d, backend=be), host)


@pytest.mark.slow
def test_bunny_grid_q8_two_level_gives_the_box32_hits():
    """bunny_grid, primary rays of a small frame: the q8 and q8g two-level images (q8 TLAS) hit
    as the box32 one, t bit for bit, on the golden model and on the RTL with the q8 decode."""
    import driver
    from driver.scenes.camera import primary_rays
    from driver.scenes.scene import load_scene
    scene = load_scene("bunny_grid")
    o, d = primary_rays(scene.camera, 20, 20)
    a = trace(build_two_level(scene.instances, format="box32"), o, d)
    assert a.hit.sum() > 30 and len(np.unique(a.instance[a.hit])) > 3
    be = driver.backend("rtl", compressed=True)
    for fmt in ("q8", "q8g"):
        bvh = build_two_level(scene.instances, format=fmt)
        assert bvh.stats["tlas_format"] == "q8"
        host = trace(bvh, o, d)
        _same_image_hits(host, a)
        _same_trace(trace(bvh, o, d, backend=be), host)


def test_q8_tlas_with_the_transform_on_the_datapath():
    """--transform datapath on a q8 two-level image, on a datapath with the q8 decode and the
    TRANSFORM operation: the driver's hits bit for bit, one TRANSFORM per instance entered."""
    import driver
    inst = random_instances(5, k=10)
    o, d = random_rays(800, 14)
    bvh = build_two_level(inst, format="q8")
    a = trace(bvh, o, d, transform="driver")
    b = trace(bvh, o, d, backend=driver.backend("golden", compressed=True, transform=True),
              transform="datapath")
    _same_trace(a, b)
    _same_ops(a.stats, b.stats)


def test_memory_model_charges_64_bytes_per_q8_tlas_node():
    """Node bytes of a q8 two-level traversal: 64 per q8 node (TLAS nodes included), 128 per
    instance entered; the RT-unit replay with a cache that holds the image misses each TLAS
    node's one line once."""
    from driver import rtunit
    inst = random_instances(6, k=12)
    o, d = random_rays(400, 15)
    bvh = build_two_level(inst, format="q8")
    res = trace(bvh, o, d, record=True)
    rec = res.record
    size = np.array([NODE_BYTES.get(t, 0) for t in range(8)])
    assert size[Q8_TYPE] == 64
    entered = rec.before != NO_CHILD
    assert res.stats["node_bytes_fetched"] == (size[NodeRef.type(rec.ptr)].sum()
                                               + INSTANCE_BYTES * entered.sum())
    tlas = (NodeRef.type(rec.ptr) == Q8_TYPE) & (NodeRef.offset(rec.ptr)
                                                  < bvh.stats["tlas_bytes"])
    assert tlas.sum() > len(o)
    below = NodeRef.offset(rec.ptr) < bvh.stats["tlas_bytes"]
    assert np.array_equal(tlas, below), "the TLAS requests are the q8 nodes below its end"
    assert (NodeRef.offset(rec.ptr[tlas]) % 64 == 0).all(), "one 64-byte line per TLAS node"
    big = rtunit.replay(rec, 16, 1, memory=rtunit.MemoryModel(cache_bytes=1 << 22),
                        datapath="rtl")
    nodes = np.concatenate([rec.ptr, rec.before[entered]])
    sz = size[NodeRef.type(nodes)]
    off = NodeRef.offset(nodes)[sz > 0]
    lines = np.unique(np.concatenate([off // 64, (off + sz[sz > 0] - 1) // 64]))
    assert big.memory["line_misses"] == len(lines) and big.verified


def test_instances_reject_bad_input():
    tri = trimesh.creation.box().triangles
    with pytest.raises(ValueError, match="singular"):
        Instances([tri], [0], np.zeros((1, 3, 4)))
    with pytest.raises(ValueError, match="does not exist"):
        Instances([tri], [1], np.eye(3, 4)[None])
    with pytest.raises(ValueError, match="finite"):
        Instances([tri], [0], np.full((1, 3, 4), np.inf))
    inst = Instances([tri], [0], np.eye(3, 4)[None])
    with pytest.raises(ValueError, match="transform must be one of"):
        trace(build_two_level(inst), [[0, 0, -3]], [[0, 0, 1]], transform="shader")


# ---- hits ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("count, size", [(5, 300), (400, 3)])   # a block each; one gather
def test_flatten_is_world_triangles_bit_for_bit(count, size):
    rng = np.random.default_rng(count)
    meshes = [rng.normal(size=(size + j, 3, 3)).astype(np.float32) * 10 for j in range(3)]
    m = rng.normal(size=(count, 3, 4)) * [1, 1, 1, 50]
    inst = Instances(meshes, rng.integers(0, 3, count), m.astype(np.float32))
    flat = inst.flatten()
    assert (len(inst.mesh) * instances_mod.FLATTEN_BLOCK > len(flat)) == (size < 64)
    ref = inst.world_triangles(np.arange(inst.triangles_total))
    assert flat.dtype == np.float32 and flat.tobytes() == ref.tobytes()


@pytest.mark.parametrize("seed", [0, 1])
def test_instanced_hits_equal_flattened(seed):
    inst = random_instances(seed)
    assert inst.mirrored.any()
    bvh = build_two_level(inst)
    flat = inst.flatten()
    o, d = random_rays(3000, seed + 10)
    a, b = trace(bvh, o, d), trace(flat, o, d)
    assert a.hit.sum() > 300
    assert_same_hits(a, b)
    assert np.array_equal(a.instance[a.hit], inst.locate(a.prim[a.hit])[0])
    assert (a.instance[~a.hit] == -1).all() and (b.instance == -1).all()
    s = a.stats
    assert s["instance_ops"] >= a.hit.sum()
    assert s["instance_ops_per_ray"] == s["instance_ops"] / 3000
    assert "instance_ops" not in b.stats
    # both faces: double-sided hits agree too (mirrored instances included)
    a2, b2 = trace(bvh, o, d, double_sided=True), trace(flat, o, d, double_sided=True)
    assert_same_hits(a2, b2)
    assert a2.hit.sum() > a.hit.sum()


def test_mirrored_instance_keeps_world_winding():
    """A mirrored copy of a single triangle faces the way its world-space vertices say."""
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    mirror = np.array([[[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0]]])       # z -> -z
    inst = Instances([tri], [0], mirror)
    assert inst.mirrored.all()
    bvh = build_two_level(inst)
    o = np.array([[0.2, 0.2, 5.0], [0.2, 0.2, -5.0]], np.float32)
    d = np.array([[0, 0, -1.0], [0, 0, 1.0]], np.float32)
    a, b = trace(bvh, o, d), trace(inst.flatten(), o, d)
    assert np.array_equal(a.hit, b.hit) and a.hit.sum() == 1


def test_any_hit_across_instances():
    """Occlusion rays through a row of instances: occluded exactly when the flattened scene says
    so, the extent carried into every instance."""
    box = trimesh.creation.box().triangles
    mats = np.array([np.hstack([np.eye(3) * 0.5, [[3.0 * i], [0], [0]]]) for i in range(6)])
    inst = Instances([box], np.zeros(6, np.int64), mats)
    bvh = build_two_level(inst)
    n = 500
    rng = np.random.default_rng(2)
    o = np.column_stack([np.full(n, -3.0), rng.uniform(-0.6, 0.6, n), rng.uniform(-0.6, 0.6, n)])
    d = np.tile([[1.0, 0.0, 0.0]], (n, 1))
    ext = rng.uniform(0.5, 20.0, n).astype(np.float32)
    a = trace(bvh, o, d, extent=ext, any_hit=True)
    b = trace(inst.flatten(), o, d, extent=ext, any_hit=True)
    assert_same_hits(a, b, any_hit=True)
    assert 0 < a.hit.sum() < n
    assert (a.t[a.hit] < ext[a.hit]).all()
    c = trace(bvh, o, d, extent=ext)
    # an any-hit ray stops at its first accepted triangle: never more instances than closest hit
    assert a.stats["instance_ops"] <= c.stats["instance_ops"]
    assert np.array_equal(c.hit, a.hit)


def test_nested_gltf_scene_graph_stays_instanced(tmp_path):
    from driver.scenes.scene import load_scene
    s = trimesh.Scene()
    ico = trimesh.creation.icosphere(1)
    s.add_geometry(ico, geom_name="ico", node_name="n0")
    for i in (1, 2):
        s.graph.update(frame_to=f"n{i}", frame_from=s.graph.base_frame, geometry="ico",
                       matrix=trimesh.transformations.translation_matrix([3.0 * i, 0, 0]))
    turn = trimesh.transformations.rotation_matrix(0.7, [0, 1, 1]) @ np.diag([0.5, 1.5, 0.8, 1])
    s.graph.update(frame_to="child", frame_from="n1", geometry="ico", matrix=turn)
    s.add_geometry(trimesh.creation.box(), geom_name="box", node_name="box",
                   transform=trimesh.transformations.translation_matrix([0, 3.0, 0]))
    path = tmp_path / "reuse.glb"
    s.export(str(path))
    scene = load_scene(path)
    inst = scene.instances
    assert inst is not None and len(inst) == 5 and len(inst.meshes) == 2
    assert scene.counts() == {"instances": 5, "instanced_triangles": 4 * 80 + 12,
                              "blas_triangles": 92}
    flat = trimesh.load(str(path), force="mesh", process=False)
    key = lambda t: np.sort(np.round(t.reshape(len(t), -1), 4), axis=0)       # noqa: E731
    assert np.allclose(key(scene.triangles), key(np.asarray(flat.triangles)), atol=1e-4)
    o, d = random_rays(800, 4, spread=8.0)
    a = trace(scene, o, d)
    b = trace(scene.triangles, o, d)
    assert a.hit.sum() > 50
    assert_same_hits(a, b)
    # without reuse a glTF stays one mesh
    one = trimesh.Scene()
    one.add_geometry(ico, geom_name="a")
    one.add_geometry(trimesh.creation.box(), geom_name="b")
    one.export(str(tmp_path / "plain.glb"))
    assert load_scene(tmp_path / "plain.glb").instances is None


def test_bunny_grid_instances_small():
    from driver.scenes.builtins import instanced_bunnies
    bunny = trimesh.creation.icosphere(3).triangles
    grid = instanced_bunnies(bunny, 4, seed=1)
    assert len(grid) == 4 and len(grid.meshes) == 1
    flat = grid.flatten()
    n = len(bunny)
    assert flat[:n, :, 0].max() < flat[n:2 * n, :, 0].min(), "copies side by side"
    assert abs(flat[..., 2].min()) < 1e-3
    with pytest.raises(ValueError):
        instanced_bunnies(bunny, 0)


@pytest.mark.parametrize("fmt", ["box32", "q8"])
def test_instanced_record_replays_with_instance_fetches(fmt):
    """The rtl fast path and the RT-unit replay of an instanced traversal: one chain per world
    ray, responses verified bit for bit, the instance nodes fetched through the node memory."""
    from driver import rtunit
    inst = random_instances(2, k=8)
    bvh = build_two_level(inst, format=fmt)
    o, d = random_rays(300, 6)
    res = trace(bvh, o, d, backend="rtl", record=True)
    rec = res.record
    assert rec.rays == 300 and len(rec.ray_words) > 300 and rec.chain is not None
    entered = rec.before != NO_CHILD
    assert entered.sum() == res.stats["instance_ops"]
    assert (NodeRef.type(rec.before[entered]) == INSTANCE_TYPE).all()
    plain = rtunit.replay(rec, 16, 1, datapath="rtl")
    assert plain.verified and plain.stats()["rays"] == 300
    # a cache that holds the whole image misses each line the chains touch exactly once: the
    # lines of every request's node and of every instance node entered
    cached = rtunit.replay(rec, 16, 1, memory=rtunit.MemoryModel(cache_bytes=1 << 22),
                           datapath="rtl")
    nodes = np.concatenate([rec.ptr, rec.before[entered]])
    size = np.array([NODE_BYTES.get(t, 0) for t in range(8)])[NodeRef.type(nodes)]
    off = NodeRef.offset(nodes)[size > 0]
    lines = np.unique(np.concatenate([off // 64, (off + size[size > 0] - 1) // 64]))
    assert cached.memory["line_misses"] == len(lines)
    assert cached.verified and cached.cycles > plain.cycles
    g = trace(bvh, o, d)
    assert np.array_equal(g.prim, res.prim) and np.array_equal(g.t, res.t)


# ---- the transform on the datapath (--transform datapath) ---------------------------------------

def _same_trace(a, b):
    """Bit-identical hits: t, primitive and instance of every ray."""
    assert np.array_equal(a.t.view(np.uint32), b.t.view(np.uint32))
    assert np.array_equal(a.prim, b.prim) and np.array_equal(a.instance, b.instance)


def _same_ops(driver_stats, datapath_stats):
    """The same traversal, and one TRANSFORM op per instance entered on the datapath."""
    a, b = driver_stats, datapath_stats
    for k in ("rays", "hits", "box_ops", "tri_ops", "instance_ops", "node_bytes_fetched"):
        assert a[k] == b[k], k
    assert a["transform_ops"] == 0 and a["ops"] == a["box_ops"] + a["tri_ops"]
    assert b["transform_ops"] == b["instance_ops"] > 0
    assert b["ops"] == b["box_ops"] + b["tri_ops"] + b["transform_ops"]
    assert b["transform_ops_per_ray"] == b["transform_ops"] / b["rays"]


@pytest.mark.parametrize("backend", ["golden", "rtl"])
def test_datapath_transform_gives_the_driver_hits(backend):
    """A random scene graph (rotations, non-uniform scales, mirrors): the transform as TRANSFORM
    requests on the backend gives the hits of the host's transform bit for bit, for closest-hit,
    any-hit and double-sided rays."""
    import driver
    inst = random_instances(3)
    assert inst.mirrored.any()
    bvh = build_two_level(inst)
    o, d = random_rays(1500, 12)
    be = driver.backend(backend, transform=True)
    closest = None
    for kw in ({}, {"any_hit": True, "extent": 15.0}, {"double_sided": True}):
        a = trace(bvh, o, d, backend=backend, transform="driver", **kw)
        b = trace(bvh, o, d, backend=be, transform="datapath", **kw)
        assert a.hit.sum() > 100
        _same_trace(a, b)
        _same_ops(a.stats, b.stats)
        assert a.transform_ops.sum() == 0
        assert np.array_equal(b.ops, a.ops + b.transform_ops)
        # one backend call per step and per step's TRANSFORM batch, each paying the latency
        for r in (a, b):
            assert r.step_requests.sum() == r.stats["ops"]
            assert r.stats["cycles"] == r.stats["ops"] + 11 * len(r.step_requests)
        assert len(b.step_requests) > len(a.step_requests)
        assert b.step_box_requests.sum() == a.step_box_requests.sum()
        closest = closest or b
    # the image says where its transform runs unless the call does
    bvh.transform = "datapath"
    c = trace(bvh, o, d, backend=backend)
    _same_trace(closest, c)
    assert c.stats["transform_ops"] == closest.stats["transform_ops"]


def test_datapath_transform_in_the_record_and_the_replay():
    """The TRANSFORM requests join the rays' request chains (the instance node is their own
    node; the harness assembles the same request words as the host); without them the chains
    are the driver's. The RT-unit replay issues each like any request: with one ray in flight
    each costs latency + turnaround (11 + 1) cycles; responses verified on the RTL. The driver's
    cycles are those measured before the datapath transform existed."""
    from driver import rtunit
    from driver.backends.harness import build_requests
    from driver.core.wire import pack_requests
    inst = random_instances(2, k=8)
    o, d = random_rays(300, 6)
    # (rtunit cycles R=16, with the default node memory): driver mode, measured on the code
    # before the transform could run on the datapath (q8: measured again with the q8 TLAS,
    # whose larger decoded boxes cost 9 more box ops than the box32 TLAS under q8 BLASes did)
    before = {"box32": (1594, 7256), "q8": (1730, 5869)}
    for fmt in ("box32", "q8"):
        bvh = build_two_level(inst, format=fmt)
        a = trace(bvh, o, d, transform="driver", record=True).record
        b = trace(bvh, o, d, transform="datapath", record=True).record
        xf = NodeRef.type(b.ptr) == INSTANCE_TYPE
        assert a.transform_ops == 0 and b.transform_ops == xf.sum() > 0
        assert b.transform_ops == (a.before != NO_CHILD).sum() and (b.before == NO_CHILD).all()
        assert (b.responses[xf, 0] == b.ray[xf]).all()              # tag: the world ray
        assert np.array_equal(build_requests(b.params, b.ray_words, b.image, b.ray, b.ptr,
                                             b.extent), pack_requests(b.requests()))
        ia, ib = a.chains()[0], b.chains()[0]
        ib = ib[~xf[ib]]
        for f in ("ray", "ptr", "responses"):
            assert np.array_equal(getattr(a, f)[ia], getattr(b, f)[ib]), f
        assert np.array_equal(a.extent[ia].view(np.uint32), b.extent[ib].view(np.uint32))
        one_a, one_b = (rtunit.replay(x, 1, 1, datapath="rtl") for x in (a, b))
        assert one_b.cycles - one_a.cycles == 12 * b.transform_ops
        assert one_b.verified and one_b.stats()["transform_ops"] == b.transform_ops
        assert one_b.stats()["tri_ops"] == one_a.stats()["tri_ops"]
        plain_a, plain_b = (rtunit.replay(x, 16, 1, datapath="rtl") for x in (a, b))
        mem = rtunit.MemoryModel()
        mem_a, mem_b = (rtunit.replay(x, 16, 1, memory=mem, datapath="rtl") for x in (a, b))
        assert (plain_a.cycles, mem_a.cycles) == before[fmt]
        assert plain_b.verified and mem_b.verified and plain_b.cycles > plain_a.cycles
        big = rtunit.MemoryModel(cache_bytes=1 << 22)                # the same lines either way
        assert (rtunit.replay(a, 16, 1, memory=big).memory["line_misses"]
                == rtunit.replay(b, 16, 1, memory=big).memory["line_misses"])


def test_datapath_transform_needs_the_operation(error_line, in_tmp):
    import driver
    from driver.cli import main
    inst = random_instances(2, k=4)
    o, d = random_rays(10, 6)
    with pytest.raises(ValueError, match="needs a backend built with the TRANSFORM operation"):
        trace(build_two_level(inst), o, d, backend=driver.backend("golden"), transform="datapath")
    glb = str(reuse_glb(in_tmp / "reuse.glb"))
    for argv, what in (
            (["render", "sphere", "--transform", "datapath"], "has no instances"),
            (["render", glb, "--transform", "datapath", "--flatten"], "--flatten"),
            (["bench", "--scene", glb, "--workload", "path", "--transform", "gpu"],
             "unknown value 'gpu'"),
            (["sweep", "--scene", glb, "--transform", "driver,datapath", "--flatten", "yes"],
             "--flatten")):
        assert main(argv + ["--size", "8", "--no-progress", "--json", "x.json"]) == 2, argv
        assert what in error_line()
        assert not (in_tmp / "x.json").exists()


def test_datapath_transform_on_the_command_line(in_tmp):
    """render (whole frame and tiles) and bench --workload with --transform datapath: the driver's
    hits and ops plus one TRANSFORM op per instance entered, recorded in the design point."""
    import json

    from driver.cli import main
    glb = str(reuse_glb(in_tmp / "reuse.glb"))
    docs = {}
    for where in ("driver", "datapath"):
        for name, argv in (("whole", ["render", glb, "--size", "12", "--rtunit"]),
                           ("tiles", ["render", glb, "--size", "12", "--workload", "path",
                                      "--tile", "6", "--backend", "golden"]),
                           ("bench", ["bench", "--scene", glb, "--workload", "shadow",
                                      "--size", "8", "--sweep-rays", "4"])):
            out = f"{name}-{where}"
            assert main(argv + ["--transform", where, "--json", f"{out}.json",
                                "--no-progress"]
                        + (["--out", f"{out}.png"] if argv[0] == "render" else [])) == 0
            docs[out] = json.loads((in_tmp / f"{out}.json").read_text())
    for name in ("whole", "tiles", "bench"):
        a, b = docs[f"{name}-driver"], docs[f"{name}-datapath"]
        fa, fb = (a.get("frame", a), b.get("frame", b))
        assert b["provenance"]["design_point"]["transform"] == "datapath"
        _same_ops(fa, fb)
        for kind, t in fb["by_type"].items():
            _same_ops(fa["by_type"][kind], t)
        if "rtunit" in fb and fb["rtunit"]:
            assert fb["rtunit"]["ops"] == fb["ops"]
            assert fb["rtunit"]["replay_datapath"] == "timing"
    assert (Image.open(in_tmp / "tiles-driver.png").tobytes()
            == Image.open(in_tmp / "tiles-datapath.png").tobytes())


def test_sweep_over_the_transform(in_tmp):
    """rayflex sweep --transform driver,datapath: one functional trace each; the datapath's
    points replay the TRANSFORM requests (on a TRANSFORM build), the driver's do not; no energy
    per ray where TRANSFORM ops have no measured energy; the CSV column."""
    import csv
    import json

    from driver.cli import main
    glb = str(reuse_glb(in_tmp / "reuse.glb"))
    assert main(["sweep", "--scene", glb, "--size", "8", "--transform", "driver,datapath",
                 "--rays-in-flight", "4", "--cache-kib", "0,16", "--json", "s.json", "--csv",
                 "s.csv", "--ideal-replay", "--no-progress"]) == 0
    doc = json.loads((in_tmp / "s.json").read_text())
    assert len(doc["functional"]) == 2 and doc["grid"]["transform"] == ["driver", "datapath"]
    pts = {(e["design_point"]["transform"], e["design_point"]["cache_kib"]): e
           for e in doc["points"]}
    for kib in (0, 16):
        a, b = pts["driver", kib], pts["datapath", kib]
        _same_ops(a, b)
        assert a["rtunit"]["ops"] == a["ops"] and b["rtunit"]["ops"] == b["ops"]
        assert b["rtunit"]["cycles"] > a["rtunit"]["cycles"]
        assert b["rtunit"]["responses_verified"] is not False
        assert b["rtunit_memory"]["responses_verified"] is not False
        assert a["energy_per_ray"]["signals"] > 0 and b["energy_per_ray"]["signals"] is None
    with open(in_tmp / "s.csv") as f:
        table = list(csv.DictReader(f))
    assert {(r["transform"], r["transform_ops"] == "0") for r in table} == {
        ("driver", True), ("datapath", False)}


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["golden", "rtl"])
def test_bunny_grid_datapath_transform_gives_the_driver_hits(backend):
    """The bunny grid, primary rays of a small frame: --transform datapath gives the hits of
    --transform driver bit for bit (t, primitive, instance), one TRANSFORM per instance entered."""
    from driver.design import DesignPoint
    from driver.render import render
    from driver.scenes.scene import load_scene
    scene = load_scene("bunny_grid")
    res = {w: render(scene, 24, 24, backend=backend, progress=False,
                     point=DesignPoint(scene="bunny_grid", transform=w))
           for w in ("driver", "datapath")}
    a, b = res["driver"].trace, res["datapath"].trace
    assert a.hit.sum() > 50 and len(np.unique(a.instance[a.hit])) > 3
    _same_trace(a, b)
    _same_ops(a.stats, b.stats)
    assert np.array_equal(res["datapath"].ops, res["driver"].ops + b.transform_ops.reshape(24, 24))


# ---- large instanced scenes ---------------------------------------------------------------------

def _small_city(side=5):
    from driver.scenes.builtins import BUILT  # noqa: F401  (the registry knows the city)
    from driver.scenes.camera import Camera
    from driver.scenes.city import city
    from driver.scenes.scene import Scene
    from driver.scenes.materials import Materials
    b = city(lambda: trimesh.creation.icosphere(2).triangles, side)
    return Scene(None, Camera(**b.camera).validate(), (24, 24), "city",
                 Materials(b.albedo, b.emission), list(b.lights), False, instances=b.instances)


def test_city_layout_is_counter_based():
    from driver.scenes.city import PITCH, city_instances, counter_uniform
    bunny = trimesh.creation.icosphere(1).triangles
    a, alb = city_instances(bunny, 6)
    b, _ = city_instances(bunny, 6)
    assert np.array_equal(a.object_to_world, b.object_to_world)
    assert len(a) == 37 and a.mesh[-1] == 3 and len(alb) == 37
    assert (a.mesh[:-1][np.arange(36) % 8 == 0] == 0).all()
    assert a.mirrored[:-1][a.mesh[:-1] == 0].any() and not a.mirrored[a.mesh != 0].any()
    # every number of instance i is a function of (seed, i, k) only
    i = np.array([3, 17, 1 << 40])
    assert np.array_equal(counter_uniform(0, i, 2), [counter_uniform(0, [x], 2)[0] for x in i])
    u = counter_uniform(1, np.arange(100_000), 0)
    assert 0 <= u.min() and u.max() < 1 and abs(u.mean() - 0.5) < 0.01
    centres = a.object_to_world[:-1, :2, 3]
    assert (centres > 0).all() and (centres < 6 * PITCH).all()


def test_city_defaults_reach_game_scale():
    from driver.scenes.city import SIDE, city_instances
    bunny_tris = 99_785
    inst, _ = city_instances(np.zeros((bunny_tris, 3, 3)) + np.arange(3)[:, None], SIDE)
    assert len(inst) >= 10_000 and inst.triangles_total >= 10 ** 8


def test_small_city_renders_every_workload_and_checks_against_embree():
    from driver.design import DesignPoint
    from driver.instances import InstancedTriangles
    from driver.render import render
    scene = _small_city()
    assert isinstance(scene.triangles, InstancedTriangles)
    assert scene.counts()["instances"] == 26
    for workload in ("primary", "shadow", "ao", "path"):
        res = render(scene, 24, 24, backend="golden", point=DesignPoint(workload=workload),
                     progress=False, check_embree=True,
                     tile=None if workload == "primary" else 16)
        s = res.stats
        assert s["instances"] == 26 and s["instanced_triangles"] == len(scene.triangles)
        assert s["hits"] > 0 and s["instance_ops"] > 0
        e = s["embree"]
        assert e["rays_compared"] > 0 and e["hit_mismatch"] == 0 and e["prim_mismatch"] == 0
        if workload != "primary":
            assert all("instance_ops" in t for t in s["by_type"].values())


def test_embree_sample_is_the_full_check_on_its_rays():
    from driver.check import check
    from driver.check import embree_sample
    inst = random_instances(4)
    bvh = build_two_level(inst)
    o, d = random_rays(600, 8)
    res = trace(bvh, o, d)
    rows, tri, prim = embree_sample(inst, o, d, np.inf, res.t, res.prim, budget=400)
    assert 0 < len(rows) < 600 and len(tri) <= 400
    got = check(tri, o[rows], d[rows], res.t[rows], prim)
    full = check(inst.flatten(), o[rows], d[rows], res.t[rows], res.prim[rows])
    assert got["hit_mismatch"] == full["hit_mismatch"] == 0
    assert got["prim_mismatch"] == full["prim_mismatch"] == 0
    assert np.array_equal(got["embree_t"], full["embree_t"])
    hit = prim >= 0
    assert np.array_equal(tri[prim[hit]], inst.flatten()[res.prim[rows][hit]])


def test_render_cli_instanced_and_flattened(in_tmp):
    import json

    from driver.cli import main
    glb = reuse_glb(in_tmp / "reuse.glb")
    base = ["render", str(glb), "--size", "12", "--backend", "golden", "--no-progress",
            "--check-embree"]
    assert main(base + ["--json", "i.json", "--out", "i.png", "--transform", "driver"]) == 0
    assert main(base + ["--json", "f.json", "--out", "f.png", "--flatten"]) == 0
    i, f = (json.loads((in_tmp / n).read_text()) for n in ("i.json", "f.json"))
    assert (i["instances"], i["instanced_triangles"], i["blas_triangles"]) == (3, 240, 80)
    assert (f["instances"], f["instanced_triangles"], f["blas_triangles"]) == (1, 240, 240)
    assert i["hits"] == f["hits"] > 0 and i["instance_ops"] > 0 and "instance_ops" not in f
    assert i["embree"]["hit_mismatch"] == f["embree"]["hit_mismatch"] == 0
    assert i["bvh"]["bytes"] < f["bvh"]["bytes"] * 0.8
    ip, fp = i["provenance"]["design_point"], f["provenance"]["design_point"]
    assert ip["transform"] == "driver" and not ip["flatten"] and fp["flatten"]


def test_flatten_refuses_a_scene_too_large(error_line):
    from driver.cli import main
    from driver.scenes.scene import load_scene
    with pytest.raises(ValueError, match="too large to flatten"):
        _small_city().flattened()
    assert load_scene("bunny_floor").flattened().instances is None
    assert main(["render", "city", "--flatten", "--backend", "golden", "--size", "8"]) == 2
    assert "too large to flatten" in error_line()


def test_instances_study_hits_on_a_small_scene(tmp_path):
    from driver.studies.instances import hits
    doc = hits(str(reuse_glb(tmp_path / "reuse.glb")), size=24)
    img = doc["images"]["box32"]
    assert img["instanced_bytes"] < img["flattened_bytes"] and img["ratio"] < 1
    p = doc["rays"]["primary"]
    assert p["rays"] == 576 and p["hits"] > 0
    assert p["hit_mismatch"] == 0 and p["prim_mismatch"] == p["edge_ties"]
    assert p["max_t_rel_diff"] <= T_REL and p["instance_ops_per_ray"] > 0
    assert doc["rays"]["shadow"]["hit_mismatch"] == 0
    assert img["flattened_over_instanced"] == img["flattened_bytes"] / img["instanced_bytes"]


def test_instances_study_transform_on_a_small_scene(in_tmp, capsys):
    """The driver vs datapath transform study: same rays and hits, the datapath's ops add one
    TRANSFORM per instance entered, its RT-unit cycles are the replays'; the JSON and the
    Markdown table; a scene without instances refused before any work."""
    import json

    from driver.cli import main as cli_main

    def main(argv):                          # the study's command: rayflex study instances
        return cli_main(["study", "instances", *argv])
    glb = str(reuse_glb(in_tmp / "reuse.glb"))
    assert main(["transform", "--scene", glb, "--size", "8", "--spp", "1", "--bounces", "1",
                 "--json", "t.json", "--no-progress"]) == 0
    doc = json.loads((in_tmp / "t.json").read_text())
    a, b = doc["transforms"]["driver"], doc["transforms"]["datapath"]
    assert doc["latency_cycles"] == 11 and set(a["by_type"]) == {"primary", "shadow", "bounce1"}
    for kind in ("frame", *a["by_type"]):
        x, y = (a, b) if kind == "frame" else (a["by_type"][kind], b["by_type"][kind])
        x, y = (x["frame"], y["frame"]) if kind == "frame" else (x, y)
        assert (x["rays"], x["hits"], x["box_ops_per_ray"]) == (y["rays"], y["hits"],
                                                                y["box_ops_per_ray"])
        assert x["transform_ops_per_ray"] == 0
        assert y["transform_ops_per_ray"] == y["instance_ops_per_ray"] > 0
        rel = doc["datapath_vs_driver"][kind]
        assert rel["ops"] == pytest.approx(y["ops"] / x["ops"] - 1) and rel["ops"] > 0
        assert rel["rtunit_cycles"] == y["rtunit"]["cycles"] / x["rtunit"]["cycles"] - 1
        assert x["embree_hit_mismatch"] == y["embree_hit_mismatch"] == 0
    out = capsys.readouterr().out
    assert out.count("| frame |") == 2 and "| datapath |" in out
    assert main(["transform", "--scene", "sphere", "--size", "8", "--json", "s.json"]) == 2
    assert "has no instances" in capsys.readouterr().err
    assert not (in_tmp / "s.json").exists()


def test_bench_frame_refuses_the_city(error_line):
    from driver.cli import main
    assert main(["bench", "--scene", "city", "--no-progress"]) == 2
    assert "too large to flatten" in error_line()


@pytest.mark.slow
def test_bunny_grid_is_21_instances_of_one_bunny():
    from driver.scenes.scene import load_scene
    scene = load_scene("bunny_grid")
    inst = scene.instances
    assert len(inst) == 22 and len(inst.meshes) == 2 and (inst.mesh[:21] == 0).all()
    assert scene.counts() == {"instances": 22, "instanced_triangles": len(scene.mesh.faces),
                              "blas_triangles": len(inst.meshes[0]) + 2}
    assert np.array_equal(scene.triangles[-2:], inst.meshes[1])     # the floor, identity


@pytest.mark.slow
def test_bunny_grid_instanced_image_and_hits_against_flattened():
    """The instanced bunny grid: at most 1/15 of the flattened image's bytes, the same hits
    (t within the transform's rounding; another triangle only across a shared edge)."""
    from driver.studies.instances import hits
    doc = hits("bunny_grid", size=96)
    assert doc["images"]["box32"]["ratio"] <= 1 / 15 and doc["images"]["q8"]["ratio"] <= 1 / 15
    p = doc["rays"]["primary"]
    assert p["hits"] > 500 and p["hit_mismatch"] == 0 and p["prim_mismatch"] == p["edge_ties"]
    assert p["max_t_rel_diff"] <= T_REL and doc["rays"]["shadow"]["hit_mismatch"] == 0
