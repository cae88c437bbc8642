"""The "golden" backend: the numpy model of ``driver.core.golden`` behind the ``Backend``
protocol."""

from __future__ import annotations

import numpy as np

from ..core.datapath import (ANGULAR, EUCLIDEAN, FLAG_NO_CULL, QUADBOX, RESPONSE_DTYPE, TRANSFORM,
                             TRIANGLE, check_requests, default_latency)
from ..core.golden import (F32, accumulate, angular_beat, canonical, euclid_beat, quadbox,
                           request_boxes, sort4, transform, triangle)


def _fields(req, rows, names):
    """The named fields of the selected rows (all rows: no copy), without copying whole records."""
    if len(rows) == len(req):
        return {f: req[f] for f in names}
    return {f: req[f][rows] for f in names}


class GoldenBackend:
    """Numpy model of the whole datapath. ``cycles`` counts an ideal pipeline: a run of n requests
    takes n + latency cycles (first request accepted to last response taken). ``compressed``: the
    build decodes q8 nodes (QUADBOX with ``FLAG_DECODE_Q8``); its default latency is one more.
    ``transform``: the build has the TRANSFORM operation (docs/transform.md)."""

    name = "golden"

    def __init__(self, extended: bool = False, disjoint: bool = False, latency: int | None = None,
                 compressed: bool = False, transform: bool = False):
        self.extended = bool(extended)
        self.disjoint = bool(disjoint)     # same results by contract; kept for a uniform interface
        self.compressed = bool(compressed)
        self.transform = bool(transform)
        self.latency = default_latency(self.compressed) if latency is None else int(latency)
        self.params = {"EXTENDED": int(self.extended), "DISJOINT": int(self.disjoint),
                       "COMPRESSED": int(self.compressed), "TRANSFORM": int(self.transform),
                       "LATENCY": self.latency}
        self.cycles = 0
        self.requests = 0
        self.euclid_acc = F32(0)
        self.angular_dot = F32(0)
        self.angular_norm = F32(0)

    def run(self, req: np.ndarray) -> np.ndarray:
        check_requests(req, self.extended, self.compressed, self.transform)
        ops = req["opcode"]
        rsp = np.zeros(len(req), RESPONSE_DTYPE)
        rsp["opcode"] = ops
        rsp["tag"] = req["tag"]
        with np.errstate(all="ignore"):
            self._boxes(req, rsp, np.flatnonzero(ops == QUADBOX))
            self._triangles(req, rsp, np.flatnonzero(ops == TRIANGLE))
            if self.extended:
                self._euclid(req, rsp, np.flatnonzero(ops == EUCLIDEAN))
                self._angular(req, rsp, np.flatnonzero(ops == ANGULAR))
            if self.transform:
                self._transforms(req, rsp, np.flatnonzero(ops == TRANSFORM))
        if len(req):
            self.cycles += len(req) + self.latency
            self.requests += len(req)
        return rsp

    def _boxes(self, req, rsp, i):
        if not len(i):
            return
        r = _fields(req, i, ("origin", "inv", "dir", "box", "qnode", "opcode", "flags", "extent"))
        boxes = request_boxes(r)
        hit, tmin = quadbox(r["origin"], r["inv"], r["dir"], boxes, r["extent"])
        order, hit, tmin = sort4(hit, tmin)
        rsp["box_index"][i] = order
        rsp["box_hit"][i] = hit
        rsp["box_tmin"][i] = tmin

    def _triangles(self, req, rsp, i):
        if not len(i):
            return
        r = _fields(req, i, ("kx", "ky", "kz", "origin", "shear", "tri", "flags"))
        k = np.stack([r["kx"], r["ky"], r["kz"]], axis=1).astype(np.intp)
        no_cull = (r["flags"] & FLAG_NO_CULL) != 0
        hit, num, den = triangle(r["origin"], k, r["shear"], r["tri"], no_cull)
        rsp["tri_hit"][i] = hit
        rsp["t_num"][i] = canonical(num)
        rsp["t_den"][i] = canonical(den)

    def _transforms(self, req, rsp, i):
        if not len(i):
            return
        r = _fields(req, i, ("matrix", "origin", "dir"))
        o2, d2 = transform(r["matrix"], r["origin"], r["dir"])
        rsp["xf_origin"][i] = canonical(o2)
        rsp["xf_dir"][i] = canonical(d2)

    def _euclid(self, req, rsp, i):
        if not len(i):
            return
        r = req[i]
        beats = euclid_beat(r["vec_a"], r["vec_b"], r["vec_mask"])
        last = r["reset_accumulator"] & 1
        acc, self.euclid_acc = accumulate(beats, last, self.euclid_acc)
        rsp["euclid_acc"][i] = canonical(acc)
        rsp["euclid_last"][i] = last

    def _angular(self, req, rsp, i):
        if not len(i):
            return
        r = req[i]
        dot, norm = angular_beat(r["vec_a"], r["vec_b"], r["vec_mask"])
        last = r["reset_accumulator"] & 1
        dacc, self.angular_dot = accumulate(dot, last, self.angular_dot)
        nacc, self.angular_norm = accumulate(norm, last, self.angular_norm)
        rsp["angular_dot"][i] = canonical(dacc)
        rsp["angular_norm"][i] = canonical(nacc)
        rsp["angular_last"][i] = last
