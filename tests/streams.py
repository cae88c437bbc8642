"""Request streams for the RTL tests, built from the golden tests' generators.

- ``mixed_stream(seed, n_box, n_tri)``: random interleaved QUADBOX/TRIANGLE requests drawn to hit
  the corner cases (from test_golden).
- ``vector_requests(rng, op, lengths)``: EUCLIDEAN/ANGULAR jobs of the given beat counts with random
  masks, reset on each job's last beat (from test_extended_golden).
- ``extended_stream(seed, ...)``: random multi-beat EUCLIDEAN and ANGULAR jobs interleaved with
  each other and with QUADBOX/TRIANGLE requests; every request carries garbage in the fields its
  opcode ignores. Returns the stream and the kind of each row (0 Euclidean, 1 angular, 2 other).
"""

from __future__ import annotations

import numpy as np

from driver import REQUEST_DTYPE
from test_extended_golden import random_vectors, vector_requests
from test_golden import mixed_stream, random_bits

__all__ = ["mixed_stream", "vector_requests", "random_vectors", "extended_stream", "interleave"]


def interleave(rng, parts):
    """Randomly interleave request arrays, keeping the order within each. Returns (stream, kind)."""
    kind = np.concatenate([np.full(len(p), k) for k, p in enumerate(parts)])
    kind = kind[rng.permutation(len(kind))]
    stream = np.zeros(len(kind), REQUEST_DTYPE)
    for k, p in enumerate(parts):
        stream[kind == k] = p
    return stream, kind


def extended_stream(seed, n_jobs=40, max_beats=12, n_box=300, n_tri=200):
    rng = np.random.default_rng(seed)
    e_jobs = vector_requests(rng, 2, rng.integers(1, max_beats + 1, n_jobs))
    a_jobs = vector_requests(rng, 3, rng.integers(1, max_beats + 1, n_jobs))
    other = mixed_stream(seed, n_box, n_tri)
    # box/triangle requests carry vector data and reset flags that must be ignored ...
    other["vec_a"], other["vec_b"] = random_vectors(rng, len(other))
    other["vec_mask"] = rng.integers(0, 2**16, len(other))
    other["reset_accumulator"] = rng.random(len(other)) < 0.5
    # ... and vector beats carry ray/box/triangle data that must be ignored
    for jobs in (e_jobs, a_jobs):
        donor = mixed_stream(seed + 1000, len(jobs), 0)
        for f in ("origin", "dir", "inv", "extent", "kx", "ky", "kz", "shear", "box", "tri"):
            jobs[f] = donor[f]
        m = rng.random(len(jobs)) < 0.1
        jobs["box"][m] = random_bits(rng, (m.sum(), 4, 6))
    return interleave(rng, (e_jobs, a_jobs, other))
