"""docs/statistics.md documents every key the commands write: render, bench (the default frame,
a workload frame, workers), sweep and power JSON on small frames."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from driver.cli import main
from support.meshes import reuse_glb

DOC = Path(__file__).resolve().parent.parent / "docs" / "statistics.md"

RUNS = {
    "render": ["render", "sphere", "--size", "8", "--check-embree", "--rtunit", "--cull-stack",
               "--out", "r.png"],
    "render_unit": ["render", "sphere", "--size", "8", "--backend", "rtunit", "--rays-in-flight",
                    "8", "--check-embree", "--out", "u.png"],
    "render_tiled": ["render", "cornell", "--size", "8", "--workload", "path", "--tile", "4",
                     "--check-embree", "--rtunit", "--out", "t.png"],
    "bench": ["bench", "--size", "8", "--pyverilator-requests", "50", "--sweep-rays", "1,4",
              "--sweep-pipelines", "1", "--repeat", "1", "--cull-stack", "--ideal-replay"],
    "render_instanced": ["render", "./reuse.glb", "--size", "8", "--transform", "datapath",
                         "--rtunit", "--check-embree", "--out", "i.png"],
    "bench_workload": ["bench", "--scene", "sphere", "--workload", "shadow", "--size", "8",
                       "--sweep-rays", "1,4", "--ideal-replay"],
    "bench_gpu": ["bench", "--scene", "sphere", "--workload", "ao", "--size", "8",
                  "--rt-preset", "rtx2060-vulkan-sim", "--rt-units", "2", "--frame", "wavefront",
                  "--ray-order", "affinity", "--ray-window", "256"],
    "bench_workers": ["bench", "--scene", "sphere", "--workload", "ao", "--size", "8",
                      "--workers", "2", "--tile", "4"],
    "sweep": ["sweep", "--scene", "sphere", "--workload", "ao", "--size", "8",
              "--rays-in-flight", "2,8", "--cache-kib", "0,16"],
    "power": ["power", "--config", "baseline-unified", "--ops", "10", "--scene", "sphere",
              "--workload", "shadow", "--size", "8"],
    "power_unit": ["power", "--backend", "rtunit", "--rays-in-flight", "4", "--stack-depth",
                   "8", "--ops", "10", "--scene", "sphere", "--workload", "shadow", "--size",
                   "4"],
}


def documented() -> tuple[set, set]:
    """(documented key names, keys whose children are data: maps) from the doc's tables: a row
    ``| `name` | meaning | unit |``; a meaning starting with "map" marks a map."""
    keys, maps = set(), set()
    for line in DOC.read_text().splitlines():
        m = re.match(r"\|\s*`([^`]+)`\s*\|([^|]*)\|", line)
        if m:
            keys.add(m.group(1))
            if m.group(2).strip().lower().startswith("map"):
                maps.add(m.group(1))
    return keys, maps


def emitted(doc, maps, path="") -> set:
    """(key name, path) of every key in ``doc``; the children of a map are data, not keys (their
    values are walked)."""
    out = set()
    if isinstance(doc, list):
        for v in doc:
            out |= emitted(v, maps, path + "[]")
    elif isinstance(doc, dict):
        for k, v in doc.items():
            out.add((k, f"{path}.{k}"))
            if k in maps and isinstance(v, dict):
                for kk, vv in v.items():
                    out |= emitted(vv, maps, f"{path}.{k}.*")
            else:
                out |= emitted(v, maps, f"{path}.{k}")
    return out


@pytest.fixture(scope="module")
def documents(tmp_path_factory):
    d = tmp_path_factory.mktemp("schema")
    import os
    cwd = os.getcwd()
    os.chdir(d)
    try:
        reuse_glb(d / "reuse.glb")                  # an instanced scene (two-level image)
        docs = {}
        for name, argv in RUNS.items():
            assert main(argv + ["--json", f"{name}.json", "--no-progress"]) == 0, name
            docs[name] = json.loads((d / f"{name}.json").read_text())
    finally:
        os.chdir(cwd)
    return docs


def test_every_key_is_documented(documents):
    keys, maps = documented()
    missing = {}
    for name, doc in documents.items():
        for key, path in emitted(doc, maps):
            if key not in keys:
                missing.setdefault(key, f"{name}: {path}")
    assert not missing, f"not in docs/statistics.md: {missing}"


def test_every_json_carries_provenance(documents):
    for name, doc in documents.items():
        prov = doc["provenance"]
        assert prov["rayflex_version"], name
        assert prov["git_commit"] is None or re.fullmatch(r"[0-9a-f]{40}", prov["git_commit"])
        assert prov["machine"]["cpu"], name
        if name != "sweep":                      # a sweep's points carry theirs
            assert prov["design_point"]["scene"] and prov["design_point"]["latency"] == 11
    assert all(e["design_point"]["workload"] == "ao" for e in documents["sweep"]["points"])


def test_one_schema_for_every_frame_and_ray_type(documents):
    """The timing objects have the same keys in every command and frame (tiles merged or not),
    and in every ray type; a wavefront frame adds ``wavefronts``, a ray order its cost."""
    shapes: dict = {}
    frames = [documents["render"], documents["render_tiled"], documents["render_instanced"],
              documents["bench"]["frame"], documents["bench_workload"]["frame"],
              documents["bench_gpu"]["frame"], *documents["sweep"]["points"]]
    for f in frames:
        for level, objs in (("frame", [f]), ("type", list(f["by_type"].values()))):
            for t in objs:
                for key in ("wavefront", "rtunit", "rtunit_memory"):
                    if t.get(key):
                        keys = set(t[key]) - {"wavefronts", "ray_order_cost"}
                        shapes.setdefault((key, level), set()).add(tuple(sorted(keys)))
    assert {k: len(v) for k, v in shapes.items()} == {
        (k, level): 1 for k in ("wavefront", "rtunit", "rtunit_memory")
        for level in ("frame", "type")}
    gpu = documents["bench_gpu"]["frame"]["rtunit_memory"]
    assert gpu["rt_units"] == 2 and gpu["warp_size"] == 32 and gpu["wavefronts"]
    assert gpu["ray_order_cost"]["ray_order"] == "affinity"
    assert documents["bench_gpu"]["provenance"]["design_point"]["rt_preset"] == \
        "rtx2060-vulkan-sim"
