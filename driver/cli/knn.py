"""``rayflex knn [DATASET]``: exact kNN with every distance on the datapath (``driver.knn``)."""

from __future__ import annotations

import sys

import numpy as np

from .. import knn
from ..core import outputs
from ..core.outputs import JSON, TABLE, Outputs
from . import options
from .common import EXIT_CHECK, PROG, check_backend, wrote

SCENES = False          # kNN reads vectors, no scene: no --lumibench-root


def add_parser(subparsers):
    p = subparsers.add_parser(
        "knn", help="exact k-nearest-neighbour search on the datapath",
        description="Exact k-nearest-neighbour search (Euclidean or cosine) with every distance "
                    "computed on the datapath's EUCLIDEAN/ANGULAR operations, checked against an "
                    "exact float64 search.")
    options.add(p, "knn")
    return p


def run(args) -> int:
    check_backend(args.backend)
    outs = Outputs(inputs=[args.dataset, args.query_file])
    out = outs.add("--out", args.out, TABLE) if args.out else None
    js = outs.add("--json", args.json, JSON) if args.json else None
    name, data = knn.load_dataset(args.dataset)
    if args.query_file:
        if args.queries is not None:
            raise ValueError("give either --queries or --query-file, not both")
        queries = knn.load_npy(args.query_file, "query file")
        if queries.shape[1] != data.shape[1]:
            raise ValueError(f"query file has {queries.shape[1]} dimensions, the dataset "
                             f"{data.shape[1]}")
        cands, qid, cid = data, np.arange(len(queries)), np.arange(len(data))
    else:
        if len(data) < 2:
            raise ValueError(f"dataset {name} has {len(data)} row: need at least 2 "
                             "(queries + candidates) or --query-file")
        n = args.queries if args.queries is not None else min(knn.DEFAULT_QUERIES, len(data) // 2)
        if not 1 <= n < len(data):
            raise ValueError(f"--queries must be in 1..{len(data) - 1}, got {n}")
        queries, cands = data[:n], data[n:]
        qid, cid = np.arange(n), np.arange(n, len(data))
    if not 1 <= args.k <= len(cands):
        raise ValueError(f"-k must be in 1..{len(cands)} (the number of candidates), "
                         f"got {args.k}")
    res = knn.knn(queries, cands, args.k, args.metric, backend=args.backend,
                  disjoint=args.disjoint, progress=not args.no_progress, query_ids=qid,
                  candidate_ids=cid)
    res.stats["dataset"] = name
    with outs.commit():
        if out:
            knn.write_neighbors(res, outs.temp(out))
        if js:
            outputs.write_json({**res.stats, "disagreements": res.disagreements}, outs.temp(js))
    print(f"dataset {name}: {len(data)} x {data.shape[1]}")
    print(knn.summary(res))
    wrote(outs.paths())
    if res.stats["unexplained_queries"]:
        print(f"{PROG}: knn: {res.stats['unexplained_queries']} queries disagree with the "
              "exact search beyond float32 rounding", file=sys.stderr)
        return EXIT_CHECK
    return 0
