"""Exact k-nearest-neighbour search with every distance computed on the RayFlex datapath.

``rayflex knn [DATASET]`` searches query vectors against a dataset (default: scikit-learn's bundled
``load_digits``, 1,797 x 64; or a 2-D ``.npy`` file) with the extended operations of
docs/datapath.md#euclidean-and-angular:

* Euclidean: one EUCLIDEAN job per (query, candidate) pair, ``ceil(D / 16)`` beats; the job's last
  beat (``reset_accumulator = 1``) returns the squared distance in ``euclid_acc``. The reported
  distance is ``sqrt`` of that float32 value (host, float64); neighbours are ranked by the float32
  squared distance itself.
* Cosine: one ANGULAR job per pair, ``ceil(D / 8)`` beats (``a`` = query, ``b`` = candidate), giving
  ``dot = q.c`` and ``norm = |c|^2``; ``|q|^2`` comes from one extra ANGULAR job of the query
  against itself (its ``norm``), so every sum is a datapath sum. The host then computes, in
  float64 from those float32 values, ``1 - dot / (sqrt(|q|^2) * sqrt(|c|^2))``; a zero vector
  (norm 0) has cosine distance 1 by convention (scikit-learn's convention too).

The tail lanes of a job's last beat are masked off (``vec_mask``). Jobs are streamed back to back
(many jobs per ``backend.run()`` call) with each job's beats consecutive, so there is never more
than one job of a kind in flight and the pipeline stays full.

Agreement: the same search is done exactly on the host (float64 numpy, same distance formula,
stable sort: ties broken by the lower candidate index) and the k-neighbour *sets* are compared per
query. A query whose sets differ is a *near tie* when float32 rounding explains the swap: the
float64 gap between the datapath's worst extra neighbour and the exact search's best missed one is
no larger than the sum of those two candidates' datapath rounding errors (|d32 - d64|); anything
else is *unexplained* (exit status 1).
"""

from __future__ import annotations

import csv
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import backends
from .backends import DEFAULT_BACKEND
from .core.datapath import ANGULAR, EUCLIDEAN, REQUEST_DTYPE
from .core.wire import ANG_LANES, EUC_LANES
from .core.progress import bar as progress_bar

F32 = np.float32
LANES = {EUCLIDEAN: EUC_LANES, ANGULAR: ANG_LANES}
METRICS = ("euclidean", "cosine")
CHUNK_BEATS = 1 << 16            # requests per backend.run() call (rounded to whole jobs)
DEFAULT_QUERIES = 100
DEFAULT_K = 5


# ------------------------------------------------------------------------------------------------
# data

def load_dataset(spec: str = "digits") -> tuple[str, np.ndarray]:
    """``"digits"`` (scikit-learn's bundled 8x8 digits, 1,797 x 64, values 0..16) or a path to a
    ``.npy`` file holding a 2-D finite numeric array. Returns (name, float64 array).
    ValueError / OSError with a one-line message on bad input."""
    if spec == "digits":
        from sklearn.datasets import load_digits
        return "digits", np.asarray(load_digits().data, dtype=np.float64)
    return Path(spec).name, load_npy(spec, "dataset")


def load_npy(path, what: str = "array") -> np.ndarray:
    """A validated 2-D, non-empty, finite (also after rounding to float32) float64 array."""
    p = Path(path)
    if p.suffix.lower() != ".npy":
        raise ValueError(f"{what} {path}: expected 'digits' or a .npy file")
    if not p.is_file():
        raise ValueError(f"{what} {path}: no such file")
    try:
        x = np.load(p, allow_pickle=False)
    except (ValueError, OSError, EOFError) as e:
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ValueError(f"{what} {path}: not a readable .npy array ({msg})") from None
    return check_matrix(x, f"{what} {path}")


def check_matrix(x, what: str = "array") -> np.ndarray:
    x = np.asarray(x)
    if x.dtype.kind not in "biuf":
        raise ValueError(f"{what}: expected a numeric array, got dtype {x.dtype}")
    if x.ndim != 2:
        raise ValueError(f"{what}: expected a 2-D array (rows x dimensions), got shape {x.shape}")
    if x.shape[0] == 0 or x.shape[1] == 0:
        raise ValueError(f"{what}: empty array of shape {x.shape}")
    x = x.astype(np.float64)
    if not np.isfinite(x).all():
        raise ValueError(f"{what}: contains NaN or infinite values")
    with np.errstate(over="ignore"):
        if not np.isfinite(x.astype(F32)).all():
            raise ValueError(f"{what}: values overflow float32")
    return x


# ------------------------------------------------------------------------------------------------
# requests

def pad(x: np.ndarray, lanes: int) -> np.ndarray:
    """float32 rows padded with zeros to a whole number of beats: (n, beats * lanes)."""
    n, d = x.shape
    beats = -(-d // lanes)
    out = np.zeros((n, beats * lanes), F32)
    out[:, :d] = x
    return out


def beat_masks(dim: int, lanes: int) -> np.ndarray:
    """vec_mask of each beat of a job over ``dim`` dimensions: full beats, then the tail."""
    beats = -(-dim // lanes)
    full = (1 << lanes) - 1
    masks = np.full(beats, full, np.uint16)
    tail = dim - (beats - 1) * lanes
    masks[-1] = (1 << tail) - 1
    return masks


def job_requests(op: int, a: np.ndarray, b: np.ndarray, ai, bi, dim: int,
                 first_tag: int = 0) -> np.ndarray:
    """The request stream of jobs ``a[ai[j]]`` vs ``b[bi[j]]`` (padded float32 rows, see ``pad``),
    each job's beats consecutive, ``reset_accumulator`` on its last beat; tag = job number
    (``first_tag + j``, mod 2^32) on every beat of the job."""
    lanes = LANES[op]
    beats = a.shape[1] // lanes
    ai = np.asarray(ai, np.intp)
    bi = np.asarray(bi, np.intp)
    jobs = len(ai)
    req = np.zeros(jobs * beats, REQUEST_DTYPE)
    req["opcode"] = op
    req["vec_a"][:, :lanes] = a[ai].reshape(jobs * beats, lanes)
    req["vec_b"][:, :lanes] = b[bi].reshape(jobs * beats, lanes)
    req["vec_mask"] = np.tile(beat_masks(dim, lanes), jobs)
    req["reset_accumulator"][beats - 1::beats] = 1
    req["tag"] = np.repeat((first_tag + np.arange(jobs, dtype=np.int64)) % 2**32, beats)
    return req


def job_results(req: np.ndarray, rsp: np.ndarray, op: int) -> np.ndarray:
    """The final accumulators of the jobs of kind ``op`` in a response stream (rows whose
    ``*_last`` flag is set), in job order: (jobs,) euclid_acc or (jobs, 2) (dot, norm)."""
    if op == EUCLIDEAN:
        last = (rsp["opcode"] == EUCLIDEAN) & (rsp["euclid_last"] == 1)
        return rsp["euclid_acc"][last]
    last = (rsp["opcode"] == ANGULAR) & (rsp["angular_last"] == 1)
    return np.stack([rsp["angular_dot"][last], rsp["angular_norm"][last]], axis=1)


@dataclass
class RunStats:
    """What streaming jobs through a backend cost."""
    jobs: int = 0
    ops: int = 0               # beats (requests)
    cycles: int = 0
    runs: int = 0              # backend.run() calls
    wall_s: float = 0.0


def run_jobs(dp, op: int, a: np.ndarray, b: np.ndarray, ai, bi, dim: int,
             stats: RunStats | None = None, bar=None, chunk_beats: int = CHUNK_BEATS):
    """Stream the jobs ``a[ai[j]]`` vs ``b[bi[j]]`` through backend ``dp``, many jobs per run()
    call, one job of this kind at a time. Returns (jobs,) float32 squared distances (EUCLIDEAN) or
    (jobs, 2) float32 (dot, norm) (ANGULAR)."""
    stats = stats if stats is not None else RunStats()
    ai = np.asarray(ai, np.intp)
    bi = np.asarray(bi, np.intp)
    beats = a.shape[1] // LANES[op]
    per_run = max(1, chunk_beats // beats)
    out = np.empty((len(ai),) if op == EUCLIDEAN else (len(ai), 2), F32)
    for s in range(0, len(ai), per_run):
        e = min(s + per_run, len(ai))
        req = job_requests(op, a, b, ai[s:e], bi[s:e], dim, first_tag=s)
        c0, t0 = dp.cycles, time.perf_counter()
        rsp = dp.run(req)
        stats.wall_s += time.perf_counter() - t0
        stats.cycles += dp.cycles - c0
        stats.ops += len(req)
        stats.jobs += e - s
        stats.runs += 1
        res = job_results(req, rsp, op)
        if len(res) != e - s:
            raise RuntimeError(f"datapath returned {len(res)} job results for {e - s} jobs")
        out[s:e] = res
        if bar is not None:
            bar.update(len(req))
    return out


# ------------------------------------------------------------------------------------------------
# distances

def cosine_from(dot, qnorm2, cnorm2) -> np.ndarray:
    """1 - dot / (sqrt(|q|^2) sqrt(|c|^2)) in float64; 1 where either vector is zero."""
    dot = np.asarray(dot, np.float64)
    den = np.sqrt(np.asarray(qnorm2, np.float64)) * np.sqrt(np.asarray(cnorm2, np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 1.0 - dot / den
    return np.where(den > 0, d, 1.0)


def exact_distances(queries: np.ndarray, cands: np.ndarray, metric: str) -> np.ndarray:
    """(Q, M) exact float64 distances (squared Euclidean, or cosine) of the original values."""
    q = np.asarray(queries, np.float64)
    c = np.asarray(cands, np.float64)
    if metric == "euclidean":
        # explicit differences (no |q|^2 - 2 q.c + |c|^2 cancellation), in blocks of queries
        out = np.empty((len(q), len(c)))
        step = max(1, (1 << 22) // (c.shape[0] * c.shape[1]))
        for s in range(0, len(q), step):
            diff = q[s:s + step, None, :] - c[None, :, :]
            out[s:s + step] = np.einsum("qmd,qmd->qm", diff, diff)
        return out
    return cosine_from(q @ c.T, (q * q).sum(1)[:, None], (c * c).sum(1)[None, :])


def topk(dist: np.ndarray, k: int) -> np.ndarray:
    """(Q, k) candidate indices of the k smallest distances per row; ties: lower index first."""
    return np.argsort(dist, axis=1, kind="stable")[:, :k]


def datapath_distances(dp, queries: np.ndarray, cands: np.ndarray, metric: str,
                       stats: RunStats | None = None, progress: bool = False):
    """(Q, M) distances with every sum on backend ``dp`` (an extended build): float32 squared
    Euclidean distances, or float64 cosine distances from float32 datapath dot/norms."""
    stats = stats if stats is not None else RunStats()
    nq, dim = queries.shape
    nc = len(cands)
    op = EUCLIDEAN if metric == "euclidean" else ANGULAR
    lanes = LANES[op]
    beats = -(-dim // lanes)
    qp, cp = pad(queries.astype(F32), lanes), pad(cands.astype(F32), lanes)
    ai = np.repeat(np.arange(nq), nc)
    bi = np.tile(np.arange(nc), nq)
    total = (nq * nc + (nq if op == ANGULAR else 0)) * beats
    with progress_bar(total, f"knn {metric}", "beat", progress, leave=False) as bar:
        if op == EUCLIDEAN:
            return run_jobs(dp, op, qp, cp, ai, bi, dim, stats, bar).reshape(nq, nc)
        qself = run_jobs(dp, op, qp, qp, np.arange(nq), np.arange(nq), dim, stats, bar)
        dn = run_jobs(dp, op, qp, cp, ai, bi, dim, stats, bar).reshape(nq, nc, 2)
    return cosine_from(dn[..., 0], qself[:, 1:2], dn[..., 1])


# ------------------------------------------------------------------------------------------------
# search + agreement

@dataclass
class KnnResult:
    """neighbors (Q, k) candidate indices (into ``candidate_ids`` space: dataset rows);
    distances (Q, k) float64 (Euclidean: sqrt of the datapath's squared distance; cosine); exact
    neighbours/distances of the float64 search; per-query agreement; stats."""
    neighbors: np.ndarray
    distances: np.ndarray
    exact_neighbors: np.ndarray
    exact_distances: np.ndarray
    query_ids: np.ndarray
    agree: np.ndarray
    disagreements: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)


def knn(queries, cands, k: int, metric: str = "euclidean", backend=DEFAULT_BACKEND,
        disjoint=False, progress=False, query_ids=None, candidate_ids=None) -> KnnResult:
    """k nearest candidates of every query with all distance sums on the datapath, compared with
    the exact float64 search. ``backend``: a name (built with extended=True) or a backend object.
    ``query_ids`` / ``candidate_ids`` name the rows in the result (default 0..n-1)."""
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose from {', '.join(METRICS)}")
    queries = check_matrix(queries, "queries")
    cands = check_matrix(cands, "candidates")
    if queries.shape[1] != cands.shape[1]:
        raise ValueError(f"queries have {queries.shape[1]} dimensions, the dataset "
                         f"{cands.shape[1]}")
    if not 1 <= k <= len(cands):
        raise ValueError(f"-k must be in 1..{len(cands)} (the number of candidates), got {k}")
    dp = backends.backend(backend, extended=True, disjoint=disjoint) if isinstance(backend, str) \
        else backend
    if not getattr(dp, "extended", False):
        raise ValueError("kNN needs an extended datapath build (extended=True)")
    qid = np.arange(len(queries)) if query_ids is None else np.asarray(query_ids)
    cid = np.arange(len(cands)) if candidate_ids is None else np.asarray(candidate_ids)

    rs = RunStats()
    t0 = time.perf_counter()
    d_dp = datapath_distances(dp, queries, cands, metric, rs, progress)
    wall = time.perf_counter() - t0
    d_ex = exact_distances(queries, cands, metric)
    nb, nb_ex = topk(d_dp, k), topk(d_ex, k)
    rows = np.arange(len(queries))[:, None]
    d_dp64 = np.asarray(d_dp, np.float64)
    agree = np.array([set(a) == set(b) for a, b in zip(nb.tolist(), nb_ex.tolist())], bool)
    dis = [_classify(i, nb[i], nb_ex[i], d_dp64[i], d_ex[i], metric, qid, cid)
           for i in np.flatnonzero(~agree)]

    if metric == "euclidean":
        dist, dist_ex = np.sqrt(d_dp64[rows, nb]), np.sqrt(d_ex[rows, nb_ex])
    else:
        dist, dist_ex = d_dp64[rows, nb], d_ex[rows, nb_ex]
    near = sum(d["near_tie"] for d in dis)
    lat = int(getattr(dp, "latency", 0))
    stats = {
        "metric": metric, "k": int(k), "queries": len(queries), "candidates": len(cands),
        "dim": int(queries.shape[1]),
        "beats_per_job": -(-queries.shape[1] // LANES[EUCLIDEAN if metric == "euclidean"
                                                       else ANGULAR]),
        "jobs": rs.jobs, "ops": rs.ops, "cycles": rs.cycles, "runs": rs.runs,
        "utilization": rs.ops / rs.cycles if rs.cycles else 0.0,
        "latency_cycles": lat, "frame_us_at_1ghz": rs.cycles / 1000,
        "sim_wall_s": rs.wall_s, "total_wall_s": wall,
        "sim_cycles_per_s": rs.cycles / rs.wall_s if rs.wall_s else 0.0,
        "backend": getattr(dp, "name", str(backend)), "extended": True,
        "disjoint": bool(getattr(dp, "disjoint", disjoint)),
        "agreement_pct": 100.0 * agree.mean(), "disagreeing_queries": int((~agree).sum()),
        "near_tie_queries": int(near), "unexplained_queries": int(len(dis) - near),
        "nonfinite_distances": int((~np.isfinite(d_dp64)).sum()),
    }
    return KnnResult(cid[nb], dist, cid[nb_ex], dist_ex, qid, agree, dis, stats)


def _classify(i, nb, nb_ex, d_dp, d_ex, metric, qid, cid) -> dict:
    """Why query i's datapath neighbour set differs from the exact one (see module doc)."""
    extra = np.setdiff1d(nb, nb_ex)        # chosen by the datapath only
    missed = np.setdiff1d(nb_ex, nb)       # chosen by the exact search only
    worst = extra[np.argmax(d_ex[extra])]
    best = missed[np.argmin(d_ex[missed])]
    gap = float(d_ex[worst] - d_ex[best])
    err = float(abs(d_dp[worst] - d_ex[worst]) + abs(d_dp[best] - d_ex[best]))
    return {"query": int(qid[i]), "datapath_only": cid[extra].tolist(),
            "exact_only": cid[missed].tolist(), "gap_f64": gap, "rounding_error": err,
            "near_tie": bool(gap <= err), "metric": metric}


# ------------------------------------------------------------------------------------------------
# output

def write_neighbors(res: KnnResult, path) -> None:
    """JSON (``{"queries": [{"query", "neighbors", "distances"}...]}``) or CSV (query, rank,
    neighbor, distance) by the extension of ``path``."""
    p = Path(path)
    if p.suffix.lower() == ".csv":
        with open(p, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["query", "rank", "neighbor", "distance"])
            for q, nb, d in zip(res.query_ids.tolist(), res.neighbors.tolist(),
                                res.distances.tolist()):
                for r, (n, x) in enumerate(zip(nb, d)):
                    w.writerow([q, r, n, repr(float(x))])
        return
    doc = {"metric": res.stats.get("metric"), "k": res.stats.get("k"),
           "queries": [{"query": q, "neighbors": nb, "distances": [_num(x) for x in d]}
                       for q, nb, d in zip(res.query_ids.tolist(), res.neighbors.tolist(),
                                           res.distances.tolist())]}
    p.write_text(json.dumps(doc) + "\n")


def _num(x):
    return float(x) if np.isfinite(x) else None


def summary(res: KnnResult) -> str:
    s = res.stats
    lines = [
        f"knn {s['metric']} k={s['k']} on {s['backend']}"
        f"{' (disjoint)' if s['disjoint'] else ''}: {s['queries']} queries x {s['candidates']} "
        f"candidates, {s['dim']} dims ({s['beats_per_job']} beats per job)",
        f"datapath: {s['jobs']} jobs, {s['ops']} beats (ops) in {s['cycles']} cycles, "
        f"utilization {s['utilization']:.4f}",
        f"frame: {s['frame_us_at_1ghz']:.1f} us at 1 GHz; simulated in {s['sim_wall_s']:.2f} s "
        f"({s['sim_cycles_per_s']:.3g} cycles/s)",
        f"agreement with exact float64 search: {s['agreement_pct']:.2f} % "
        f"({s['disagreeing_queries']} disagreeing queries: {s['near_tie_queries']} float32 near "
        f"ties, {s['unexplained_queries']} unexplained)",
    ]
    for d in res.disagreements[:5]:
        lines.append(f"  query {d['query']}: datapath {d['datapath_only']} vs exact "
                     f"{d['exact_only']}, float64 gap {d['gap_f64']:.3g}, rounding "
                     f"{d['rounding_error']:.3g} -> "
                     f"{'near tie' if d['near_tie'] else 'UNEXPLAINED'}")
    if len(res.disagreements) > 5:
        lines.append(f"  ... {len(res.disagreements) - 5} more (see --json)")
    if s["nonfinite_distances"]:
        lines.append(f"warning: {s['nonfinite_distances']} datapath distances overflowed "
                     "float32 (inf/NaN)")
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------
# command line
