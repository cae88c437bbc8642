"""Golden-backend throughput on a realistic QUADBOX/TRIANGLE mix; prints one JSON object.

    python bench/golden_bench.py [--n 1000000] [--box-frac 0.7] [--chunk 0] [--repeats 3]
                                 [--profile] [--json PATH]

Requests: random rays (prepare_rays, random directions, origins in a 20^3 cube, extent inf or 50),
QUADBOX requests with four boxes scattered around points on each ray (about half the boxes hit),
TRIANGLE requests with a random triangle near a point on each ray (random winding; about 10 % hit).
The stream is interleaved at random, as traversal traffic is. Hit rates are reported. Request
generation is not timed. ``--chunk K`` runs the
stream as successive ``run()`` calls of K requests (0 = one call), as a traversal loop would.
``requests_per_s`` is the best of ``--repeats`` timed runs (wall clock); ``requests_per_cpu_s`` uses
the process CPU time, which is steadier on a shared machine (the golden model is single-threaded).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time

import numpy as np

import driver
from driver import QUADBOX, TRIANGLE

F32 = np.float32
TARGET = 1_000_000


def make_requests(n: int, box_frac: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    o = rng.uniform(-10, 10, (n, 3)).astype(F32)
    d = rng.normal(size=(n, 3)).astype(F32)
    d[(d == 0).all(axis=1)] = [0, 0, 1]
    req = driver.prepare_rays(o, d, rng.choice([np.inf, 50.0], n).astype(F32))
    is_box = rng.random(n) < box_frac
    req["opcode"] = np.where(is_box, QUADBOX, TRIANGLE)
    # boxes: centred near points along the ray, half-size 0.1 .. 2, offset so about half hit
    t = rng.uniform(0, 20, (n, 4, 1))
    c = o[:, None, :] + t * d[:, None, :] + rng.normal(scale=1.0, size=(n, 4, 3))
    h = rng.uniform(0.1, 2, (n, 4, 3))
    req["box"] = np.concatenate([c - h, c + h], axis=2).astype(F32)
    # triangles: a random triangle around a point the ray passes near
    p = o + rng.uniform(0.5, 20, (n, 1)) * d + rng.normal(scale=0.3, size=(n, 3))
    req["tri"] = (p[:, None, :] + rng.normal(size=(n, 3, 3))).astype(F32)
    req["box"][~is_box] = 0
    req["tri"][is_box] = 0
    return req


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=TARGET, help="requests (default 1 M)")
    ap.add_argument("--box-frac", type=float, default=0.7, help="fraction of QUADBOX requests")
    ap.add_argument("--chunk", type=int, default=0, help="requests per run() call (0 = all)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--profile", action="store_true", help="cProfile one run, print to stderr")
    ap.add_argument("--json", help="also write the JSON here")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    req = make_requests(args.n, args.box_frac, args.seed)
    gen_s = time.perf_counter() - t0
    chunk = args.chunk if args.chunk > 0 else max(args.n, 1)
    chunks = [req[i:i + chunk] for i in range(0, args.n, chunk)]

    def one_pass():
        g = driver.backend("golden")
        c, t = time.process_time(), time.perf_counter()
        out = [g.run(c) for c in chunks]
        return time.perf_counter() - t, time.process_time() - c, out, g

    if args.profile:
        import cProfile
        import pstats
        prof = cProfile.Profile()
        prof.enable()
        one_pass()
        prof.disable()
        pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(20)

    times, cpu = [], []
    for _ in range(max(args.repeats, 1)):
        s, c, out, g = one_pass()
        times.append(s)
        cpu.append(c)
    rsp = np.concatenate(out)
    box = rsp["opcode"] == QUADBOX
    best = min(times)
    result = {
        "backend": "golden",
        "n": args.n,
        "box_requests": int(box.sum()),
        "tri_requests": int((~box).sum()),
        "chunk": chunk,
        "seconds": round(best, 4),
        "seconds_all": [round(x, 4) for x in times],
        "requests_per_s": round(args.n / best) if best > 0 else None,
        "cpu_seconds": round(min(cpu), 4),
        "requests_per_cpu_s": round(args.n / min(cpu)) if min(cpu) > 0 else None,
        "target_requests_per_s": TARGET,
        "meets_target": bool(best > 0 and args.n / best >= TARGET),
        "box_hit_rate": round(float(rsp["box_hit"][box].mean()), 3) if box.any() else None,
        "tri_hit_rate": round(float(rsp["tri_hit"][~box].mean()), 3) if (~box).any() else None,
        "cycles": int(g.cycles),
        "generate_s": round(gen_s, 3),
        "numpy": np.__version__,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    text = json.dumps(result)
    print(text)
    if args.json:
        with open(args.json, "w") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
