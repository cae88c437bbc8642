"""``driver.knn`` / ``rayflex knn``: datapath distances bit-exact vs golden, kNN vs an exact search,
multi-beat jobs interleaved with other work, the CLI outputs and its one-line errors.

The default suite builds one extra RTL configuration (extended, unified); the disjoint build and
the full-digits runs are under ``-m slow``.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import driver
from driver import ANGULAR, EUCLIDEAN
from driver.cli import main
from driver.knn import (LANES, RunStats, _classify, beat_masks, check_matrix, datapath_distances,
                        exact_distances, job_requests, job_results, knn, pad, run_jobs, topk)
from support.streams import interleave, mixed_stream

F32 = np.float32


@pytest.fixture(scope="module")
def digits():
    from sklearn.datasets import load_digits
    return load_digits().data


def bits(x):
    return np.ascontiguousarray(x, F32).view(np.uint32)


def random_data(seed, n, dim, scale=1.0):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=(n, dim)) * scale).astype(F32)


# -------------------------------------------------------------------------------------------------
# request building


@pytest.mark.parametrize("dim,lanes,want", [(1, 16, [0x1]), (16, 16, [0xFFFF]),
                                            (17, 16, [0xFFFF, 0x1]), (64, 16, [0xFFFF] * 4),
                                            (20, 8, [0xFF, 0xFF, 0xF]), (8, 8, [0xFF])])
def test_beat_masks(dim, lanes, want):
    assert beat_masks(dim, lanes).tolist() == want


def test_job_requests_layout():
    a = pad(random_data(0, 3, 20), 8)
    b = pad(random_data(1, 5, 20), 8)
    req = job_requests(ANGULAR, a, b, [2, 0], [4, 1], 20, first_tag=7)
    assert len(req) == 6                                 # 2 jobs x 3 beats
    assert (req["opcode"] == ANGULAR).all()
    assert req["reset_accumulator"].tolist() == [0, 0, 1, 0, 0, 1]
    assert req["vec_mask"].tolist() == [0xFF, 0xFF, 0xF] * 2
    assert req["tag"].tolist() == [7, 7, 7, 8, 8, 8]
    assert (req["vec_a"][1, :8] == a[2, 8:16]).all() and (req["vec_b"][5, :8] == b[1, 16:24]).all()
    assert not req["vec_a"][:, 8:].any()                 # angular uses lanes 0..7 only


# -------------------------------------------------------------------------------------------------
# bit-exact datapath distances vs golden


def tree_f32(x):
    """Independent float32 tree over the last axis (docs/datapath.md#euclidean-and-angular)."""
    while x.shape[-1] > 1:
        h = x.shape[-1] // 2
        x = x[..., :h] + x[..., h:]
    return x[..., 0]


def reference_jobs(op, q, c, dim):
    """Independent float32 computation of every (q, c) job's final accumulator(s)."""
    lanes = LANES[op]
    qp, cp = pad(q, lanes), pad(c, lanes)
    beats = qp.shape[1] // lanes
    qa = qp.reshape(len(q), 1, beats, lanes)
    cb = cp.reshape(1, len(c), beats, lanes)
    if op == EUCLIDEAN:
        d = qa - cb
        per = [tree_f32(d * d)]
    else:
        per = [tree_f32(np.broadcast_to(qa * cb, (len(q), len(c), beats, lanes))),
               tree_f32(np.broadcast_to(cb * cb, (len(q), len(c), beats, lanes)))]
    out = []
    for p in per:
        acc = np.zeros(p.shape[:2], F32)
        for i in range(beats):
            acc = acc + p[..., i]
        out.append(acc.reshape(-1))
    return out[0] if op == EUCLIDEAN else np.stack(out, axis=1)


def _jobs(dp, op, q, c, garbage_tail=False):
    dim = q.shape[1]
    lanes = LANES[op]
    qp, cp = pad(q, lanes), pad(c, lanes)
    if garbage_tail and dim % lanes:
        qp[:, dim:] = 1e30            # masked lanes must not contribute (would overflow to inf)
        cp[:, dim:] = -7.0
    ai = np.repeat(np.arange(len(q)), len(c))
    bi = np.tile(np.arange(len(c)), len(q))
    return run_jobs(dp, op, qp, cp, ai, bi, dim, chunk_beats=500)


DIMS = [1, 7, 8, 9, 16, 17, 33, 64, 100]


@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR], ids=["euclidean", "angular"])
@pytest.mark.parametrize("name", ["golden", "rtl"])
def test_distances_bit_exact(name, op):
    dp = driver.backend(name, extended=True)
    for dim in DIMS:
        q = random_data(dim, 6, dim, scale=3.0)
        c = random_data(dim + 1000, 40, dim, scale=3.0)
        got = _jobs(dp, op, q, c, garbage_tail=True)
        assert (bits(got) == bits(reference_jobs(op, q, c, dim))).all(), dim


def test_rtl_equals_golden_on_awkward_values():
    """Wide dynamic range, subnormals and cancellation: rtl and golden bit-equal."""
    rng = np.random.default_rng(5)
    q = (rng.normal(size=(8, 37)) * 10.0 ** rng.integers(-40, 18, (8, 37))).astype(F32)
    c = (q[rng.integers(0, 8, 50)] * (1 + rng.normal(size=(50, 37)) * 1e-6)).astype(F32)
    for op in (EUCLIDEAN, ANGULAR):
        with np.errstate(all="ignore"):
            g = _jobs(driver.backend("golden", extended=True), op, q, c)
            r = _jobs(driver.backend("rtl", extended=True), op, q, c)
        assert (bits(g) == bits(r)).all()


@pytest.mark.slow
@pytest.mark.parametrize("name,disjoint", [("rtl", True), ("pyverilator", False)])
def test_distances_bit_exact_other_builds(name, disjoint):
    dp = driver.backend(name, extended=True, disjoint=disjoint)
    for op in (EUCLIDEAN, ANGULAR):
        for dim in (9, 64) if name == "pyverilator" else DIMS:
            q = random_data(dim, 3, dim, scale=3.0)
            c = random_data(dim + 7, 12, dim, scale=3.0)
            got = _jobs(dp, op, q, c, garbage_tail=True)
            assert (bits(got) == bits(reference_jobs(op, q, c, dim))).all(), (op, dim)


# -------------------------------------------------------------------------------------------------
# interleaving: multi-beat jobs mixed with the other kind and with box/triangle requests


@pytest.mark.parametrize("name,pressure", [("golden", 0.0), ("rtl", 0.0), ("rtl", 0.5)],
                         ids=["golden", "rtl", "rtl-gaps-stalls"])
def test_interleaved_jobs_give_same_distances(name, pressure):
    dim = 45                                              # 3 Euclidean beats, 6 angular beats
    q, c = random_data(11, 5, dim), random_data(12, 30, dim)
    ai, bi = np.repeat(np.arange(5), 30), np.tile(np.arange(30), 5)
    eq, ec = pad(q, 16), pad(c, 16)
    aq, ac = pad(q, 8), pad(c, 8)
    e_req = job_requests(EUCLIDEAN, eq, ec, ai, bi, dim)
    a_req = job_requests(ANGULAR, aq, ac, ai, bi, dim)
    other = mixed_stream(3, 400, 300)
    mixed, _ = interleave(np.random.default_rng(4), [e_req, a_req, other])
    opts = {"gaps": pressure, "stalls": pressure, "seed": 9} if pressure else {}
    with np.errstate(all="ignore"):
        rsp = driver.backend(name, extended=True, **opts).run(mixed)
        alone = driver.backend("golden", extended=True)
        other_alone = driver.backend("golden").run(other)
    e_want = job_results(e_req, alone.run(e_req), EUCLIDEAN)
    a_want = job_results(a_req, alone.run(a_req), ANGULAR)
    assert (bits(job_results(mixed, rsp, EUCLIDEAN)) == bits(e_want)).all()
    assert (bits(job_results(mixed, rsp, ANGULAR)) == bits(a_want)).all()
    assert (bits(e_want) == bits(reference_jobs(EUCLIDEAN, q, c, dim))).all()
    assert (bits(a_want) == bits(reference_jobs(ANGULAR, q, c, dim))).all()
    # the box/triangle requests are unaffected by the vector jobs around them
    box = np.isin(rsp["opcode"], [driver.QUADBOX, driver.TRIANGLE])
    for f in ("box_index", "box_hit", "box_tmin", "tri_hit", "t_num", "t_den"):
        assert (np.ascontiguousarray(rsp[f][box]).view(np.uint8)
                == np.ascontiguousarray(other_alone[f]).view(np.uint8)).all(), f


# -------------------------------------------------------------------------------------------------
# kNN vs the exact search


@pytest.mark.parametrize("metric", ["euclidean", "cosine"])
@pytest.mark.parametrize("name", ["golden", "rtl"])
def test_knn_digits_slice_equals_exact(digits, name, metric):
    q, c = digits[:10], digits[10:310]
    res = knn(q, c, 7, metric, backend=name, candidate_ids=np.arange(10, 310))
    d = exact_distances(q, c, metric)
    want = np.argsort(d, axis=1, kind="stable")[:, :7] + 10
    assert (res.neighbors == want).all()              # same sets, and same order
    assert res.agree.all() and res.stats["agreement_pct"] == 100.0
    assert res.stats["disagreeing_queries"] == 0
    beats = 4 if metric == "euclidean" else 8
    jobs = 10 * 300 + (10 if metric == "cosine" else 0)
    assert res.stats["jobs"] == jobs and res.stats["ops"] == jobs * beats
    assert res.stats["cycles"] >= res.stats["ops"]
    assert res.stats["utilization"] > 0.99
    if metric == "euclidean":                          # digits: exact in float32 -> equal
        assert np.array_equal(res.distances, np.sqrt(d[np.arange(10)[:, None], want - 10]))


def test_knn_matches_scikit_learn(digits):
    from sklearn.neighbors import NearestNeighbors
    q, c = digits[:10], digits[10:310]
    res = knn(q, c, 5, "euclidean", backend="golden")
    nn = NearestNeighbors(n_neighbors=5, algorithm="brute").fit(c)
    dist, ind = nn.kneighbors(q)
    assert all(set(a) == set(b) for a, b in zip(res.neighbors.tolist(), ind.tolist()))
    assert np.allclose(res.distances, dist)
    res = knn(q, c, 5, "cosine", backend="golden")
    nn = NearestNeighbors(n_neighbors=5, algorithm="brute", metric="cosine").fit(c)
    dist, ind = nn.kneighbors(q)
    assert all(set(a) == set(b) for a, b in zip(res.neighbors.tolist(), ind.tolist()))
    assert np.allclose(res.distances, dist, atol=1e-12)


def test_cosine_zero_vector_and_ties_by_index():
    c = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 0, 0]], float)
    q = np.array([[3, 0, 0], [0, 0, 0]], float)
    res = knn(q, c, 3, "cosine", backend="golden")
    assert res.neighbors[0].tolist() == [1, 2, 4]      # three exact ties at 0: lowest index first
    assert np.allclose(res.distances[0], 0)
    assert res.neighbors[1].tolist() == [0, 1, 2]      # zero query: every distance is 1
    assert (res.distances[1] == 1).all()
    e = knn(c, c, 2, "euclidean", backend="golden")
    assert e.neighbors[1].tolist() == [1, 4] and e.neighbors[4].tolist() == [1, 4]
    assert e.agree.all()


def test_float_data_near_ties_are_classified():
    """Random non-integer data: float32 rounding may reorder near ties; every disagreement must
    then be explained by rounding, and the rest agree."""
    rng = np.random.default_rng(8)
    base = rng.normal(size=(200, 40))
    c = np.concatenate([base, base[:100] + rng.normal(size=(100, 40)) * 1e-7])
    q = base[:20] + rng.normal(size=(20, 40)) * 1e-3
    for metric in ("euclidean", "cosine"):
        res = knn(q, c, 3, metric, backend="golden")
        assert res.stats["unexplained_queries"] == 0
        assert res.stats["near_tie_queries"] >= 1           # the data does make near ties
        assert res.stats["agreement_pct"] >= 50
        for d in res.disagreements:
            assert 0 <= d["gap_f64"] <= d["rounding_error"] < 1e-4


def test_classify_gap_and_rounding():
    d_ex = np.array([0.0, 1.0, 1.0 + 1e-9, 5.0])
    near = _classify(0, np.array([0, 2]), np.array([0, 1]), d_ex + [0, 2e-9, -2e-9, 0], d_ex,
                     "euclidean", np.arange(1), np.arange(4))
    assert near["near_tie"] and near["datapath_only"] == [2] and near["exact_only"] == [1]
    assert near["gap_f64"] == pytest.approx(1e-9)
    far = _classify(0, np.array([0, 3]), np.array([0, 1]), d_ex, d_ex, "euclidean",
                    np.arange(1), np.arange(4))
    assert not far["near_tie"]


def test_topk_stable_and_exact_distances():
    d = np.array([[3.0, 1.0, 1.0, 0.5]])
    assert topk(d, 3).tolist() == [[3, 1, 2]]
    x = np.array([[0.0, 0.0], [3.0, 4.0]])
    assert exact_distances(x, x, "euclidean").tolist() == [[0, 25], [25, 0]]


def test_datapath_distances_stats():
    q, c = random_data(1, 3, 20), random_data(2, 7, 20)
    rs = RunStats()
    d = datapath_distances(driver.backend("golden", extended=True), q, c, "cosine", rs)
    assert d.shape == (3, 7)
    assert rs.jobs == 3 + 21 and rs.ops == rs.jobs * 3
    assert np.allclose(d, exact_distances(q, c, "cosine"), atol=1e-5)


def test_knn_needs_extended_build():
    with pytest.raises(ValueError, match="extended"):
        knn(np.ones((1, 3)), np.ones((2, 3)), 1, backend=driver.backend("golden"))


@pytest.mark.slow
@pytest.mark.parametrize("metric", ["euclidean", "cosine"])
def test_full_digits_rtl(metric, tmp_path):
    assert main(["knn", "--metric", metric, "--no-progress", "--json-stats",
                 str(tmp_path / "s.json")]) == 0
    s = json.loads((tmp_path / "s.json").read_text())
    assert s["queries"] == 100 and s["candidates"] == 1697 and s["agreement_pct"] == 100.0


# -------------------------------------------------------------------------------------------------
# command line


def test_cli_digits_summary_and_outputs(capsys, in_tmp):
    assert main(["knn", "--queries", "5", "-k", "3", "--backend", "golden", "--no-progress",
                 "--out", "nb.json", "--json-stats", "s.json"]) == 0
    out = capsys.readouterr().out
    for word in ("queries", "candidates", "beats", "cycles", "utilization", "us at 1 GHz",
                 "agreement", "100.00 %", "0 disagreeing"):
        assert word in out, word
    doc = json.loads((in_tmp / "nb.json").read_text())
    assert len(doc["queries"]) == 5 and doc["k"] == 3 and doc["metric"] == "euclidean"
    first = doc["queries"][0]
    assert first["query"] == 0 and len(first["neighbors"]) == 3
    assert min(first["neighbors"]) >= 5                   # candidates are the other rows
    s = json.loads((in_tmp / "s.json").read_text())
    for key in ("queries", "candidates", "ops", "cycles", "utilization", "frame_us_at_1ghz",
                "agreement_pct", "disagreeing_queries", "backend", "dataset"):
        assert key in s, key
    assert s["queries"] == 5 and s["candidates"] == 1792 and s["dataset"] == "digits"
    assert s["ops"] == 5 * 1792 * 4


def test_cli_npy_dataset_query_file_csv(in_tmp, capsys):
    rng = np.random.default_rng(0)
    data = rng.integers(-8, 9, (60, 23)).astype(np.float64)
    np.save(in_tmp / "d.npy", data)
    np.save(in_tmp / "q.npy", data[:4] + 0.25)
    assert main(["knn", "d.npy", "--query-file", "q.npy", "--metric", "cosine", "-k", "4",
                 "--backend", "golden", "--no-progress", "--out", "nb.csv"]) == 0
    assert "4 queries x 60 candidates" in capsys.readouterr().out
    rows = list(csv.DictReader(open(in_tmp / "nb.csv")))
    assert len(rows) == 16 and rows[0].keys() == {"query", "rank", "neighbor", "distance"}
    assert rows[0]["neighbor"] == "0"                     # q0 is data[0] shifted a little
    want = topk(exact_distances(data[:4] + 0.25, data, "cosine"), 4)
    got = np.array([int(r["neighbor"]) for r in rows]).reshape(4, 4)
    assert (got == want).all()


def test_cli_rtl_small(in_tmp, capsys):
    np.save(in_tmp / "d.npy", random_data(3, 40, 70).astype(np.float64))
    assert main(["knn", "d.npy", "--queries", "4", "-k", "2", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "on rtl" in out and "agreement" in out


def _bad_inputs(d):
    np.save(d / "one_d.npy", np.arange(5.0))
    np.save(d / "empty.npy", np.zeros((0, 4)))
    np.save(d / "nan.npy", np.array([[1.0, np.nan], [2.0, 3.0]]))
    np.save(d / "big.npy", np.array([[1e300, 0.0], [2.0, 3.0]]))
    np.save(d / "obj.npy", np.array([[1, "a"]], dtype=object), allow_pickle=True)
    np.save(d / "str.npy", np.array([["a", "b"]]))
    np.save(d / "ok.npy", np.ones((10, 3)))
    np.save(d / "q4.npy", np.ones((2, 4)))
    (d / "junk.npy").write_bytes(b"not numpy")
    (d / "x.txt").write_text("1 2\n")


@pytest.mark.parametrize("argv,fragment", [
    (["missing.npy"], "no such file"),
    (["x.txt"], ".npy"),
    (["junk.npy"], "not a readable"),
    (["one_d.npy"], "2-D"),
    (["empty.npy"], "empty"),
    (["nan.npy"], "NaN"),
    (["big.npy"], "overflow"),
    (["obj.npy"], "not a readable"),
    (["str.npy"], "numeric"),
    (["ok.npy", "-k", "0"], "-k"),
    (["ok.npy", "-k", "10"], "-k"),
    (["ok.npy", "--queries", "10"], "--queries"),
    (["ok.npy", "--queries", "0"], "--queries"),
    (["ok.npy", "--query-file", "q4.npy"], "dimensions"),
    (["ok.npy", "--query-file", "ok.npy", "--queries", "2"], "not both"),
    (["ok.npy", "--out", "nb.txt"], ".json or .csv"),
    (["ok.npy", "--json-stats", "nodir/s.json"], "does not exist"),
    (["ok.npy", "--backend", "nope"], "unknown backend"),
])
def test_cli_bad_inputs_exit_2_one_line(in_tmp, error_line, argv, fragment):
    _bad_inputs(in_tmp)
    extra = [] if "--backend" in argv else ["--backend", "golden"]
    assert main(["knn", *argv, *extra, "--no-progress"]) == 2
    assert fragment in error_line()


def test_cli_bad_metric_is_usage_error(capsys):
    with pytest.raises(SystemExit) as e:
        main(["knn", "--metric", "manhattan"])
    assert e.value.code == 2


def test_check_matrix_accepts_ints():
    assert check_matrix(np.ones((2, 2), np.int16)).dtype == np.float64


def test_cli_help_lists_knn(capsys):
    with pytest.raises(SystemExit):
        main(["knn", "--help"])
    assert "--metric" in capsys.readouterr().out
