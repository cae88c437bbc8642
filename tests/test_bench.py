"""``rayflex bench`` on a tiny frame: every JSON key, consistent statistics, the sweep plot,
one-line errors."""

from __future__ import annotations

import json

import pytest
from PIL import Image

from driver.cli import main
from driver.design import DesignPoint
from support.prebuild import SUITE_RAYS

COUNTS = ("rays", "hits", "box_ops", "tri_ops", "ops", "latency_cycles", "box_ops_per_ray",
          "tri_ops_per_ray", "node_bytes_fetched", "backend")
TIMING = ("wavefront", "rtunit", "rtunit_memory")
TOP = ("provenance", "scene", "width", "height", "frame", "rtl_cycles_per_s", "pyverilator",
       "rtl_vs_pyverilator_speedup", "golden_rays_per_s", "golden_matches_rtl",
       "embree_rays_per_s", "embree_build_s", "bvh_build_s", "rtunit_sweep")


@pytest.fixture(scope="module")
def doc(tmp_path_factory):
    d = tmp_path_factory.mktemp("bench")
    out = d / "bench.json"
    assert main(["bench", "--size", "16", "--json", str(out), "--pyverilator-requests", "300",
                 "--sweep-rays", "1,4,16,64", "--sweep-pipelines", "1,2", "--ideal-replay",
                 "--no-progress"]) == 0
    data = json.loads(out.read_text())
    data["_dir"] = d
    return data


def test_all_keys(doc):
    assert set(TOP) <= set(doc) and "targets" not in doc
    f = doc["frame"]
    assert set(COUNTS) <= set(f) and set(TIMING) <= set(f)
    for k in ("embree", "wall_s", "wall_parts_s", "bvh", "by_type"):
        assert k in f, k
    # the default frame and its one ray type carry the same counts; the ray type's RT-unit
    # objects hold its own rays' figures (the frame's: schedule, warps, memory levels too)
    prim = f["by_type"]["primary"]
    assert {k: prim[k] for k in COUNTS + ("wavefront",)} == \
        {k: f[k] for k in COUNTS + ("wavefront",)}
    for key in ("rtunit", "rtunit_memory"):
        same = set(prim[key]) & set(f[key]) - {"sim_wall_s"}
        assert {"cycles", "latency_p95", "rays", "ops"} <= same
        assert {k: prim[key][k] for k in same} == {k: f[key][k] for k in same}
    assert set(f["embree"]) >= {"rays_compared", "hit_mismatch", "prim_mismatch", "edge_ties",
                                "max_t_rel_err"}
    assert set(doc["pyverilator"]) >= {"requests", "cycles", "wall_s", "cycles_per_s"}
    prov = doc["provenance"]
    assert set(prov["machine"]) >= {"cpu", "cores"}
    assert prov["machine"]["cpu"] and prov["machine"]["cores"] >= 1
    assert prov["rayflex_version"] and prov["design_point"]["size"] == 16
    assert prov["git_commit"] is None or len(prov["git_commit"]) == 40
    for k in ("rtl_cycles_per_s", "rtl_vs_pyverilator_speedup", "golden_rays_per_s",
              "embree_rays_per_s", "bvh_build_s"):
        assert doc[k] > 0, k


def test_frame_statistics_consistent(doc):
    f = doc["frame"]
    assert doc["scene"] == "bunny" and doc["width"] == doc["height"] == 16
    assert f["rays"] == 256 and f["backend"] == "rtl"
    assert f["ops"] == f["box_ops"] + f["tri_ops"]
    for key in TIMING:
        t = f[key]
        assert t["cycles"] >= f["ops"] + f["latency_cycles"]
        assert t["utilization"] == pytest.approx(f["ops"] / t["cycles"], rel=1e-12)
        assert t["frame_us_at_1ghz"] == pytest.approx(t["cycles"] / 1000)
    r = f["rtunit"]
    assert r["pipelines"] == 1 and r["rays_in_flight"] == 64 and r["replay_datapath"] == "timing"
    assert (r["rt_units"], r["warp_size"], r["frame_schedule"]) == (1, 1, "one-kernel")
    assert f["embree"]["hit_mismatch"] == 0 and f["embree"]["rays_compared"] == 256
    assert doc["golden_matches_rtl"] is True
    runs = doc["rtl_cycles_per_s_runs"]
    assert doc["repeat"] == 3 and len(runs) == 3 and min(runs) > 0
    assert runs[0] == f["wavefront"]["sim_cycles_per_s"]       # the traversal's own pass
    assert doc["rtl_cycles_per_s"] == max(runs)
    pv = doc["pyverilator"]
    assert pv["requests"] == 300 and pv["cycles"] >= 300 + f["latency_cycles"]
    assert pv["responses_match_frame"] and pv["rtl_same_stream_match"]
    assert pv["rtl_same_stream_cycles"] == pv["cycles"]      # same handshakes, same cycles
    assert pv["cycles_equal_every_run"] and len(pv["cycles_per_s_runs"]) == 3
    assert pv["cycles_per_s"] == max(pv["cycles_per_s_runs"])
    assert doc["rtl_vs_pyverilator_speedup"] == pytest.approx(
        doc["rtl_cycles_per_s"] / pv["cycles_per_s"])


def test_sweep_and_plot(doc):
    sw = doc["rtunit_sweep"]
    assert sw["width"] == 16 and len(sw["points"]) == 8
    pts = {(p["pipelines"], p["rays_in_flight"]): p for p in sw["points"]}
    assert set(pts) == {(p, r) for p in (1, 2) for r in (1, 4, 16, 64)}
    assert pts[1, 1]["cycles"] >= sw["ops"] * 11
    for p in pts.values():
        assert p["replay_datapath"] == "timing"
        assert p["utilization"] == pytest.approx(sw["ops"] / (p["pipelines"] * p["cycles"]))
        assert p["frame_us_at_1ghz"] == pytest.approx(p["cycles"] / 1000)
    png = doc["_dir"] / "bench_rtunit.png"
    assert sw["plot"] == str(png)
    with Image.open(png) as im:
        assert im.format == "PNG" and im.size[0] > 300


def test_table_printed(doc, capsys):
    from driver.bench import table
    text = table({k: v for k, v in doc.items() if k != "_dir"})
    assert "utilization" in text and "pyverilator" in text and "sweep P=2" in text


@pytest.mark.parametrize("argv", [
    ["bench", "--size", "0"],
    ["bench", "--rays-in-flight", "0"],
    ["bench", "--pipelines", "0"],
    ["bench", "--sweep-rays", "1,x"],
    ["bench", "--sweep-pipelines", "0"],
    ["bench", "--json", "/nonexistent-dir/x.json"],
    ["bench", "--repeat", "0"],
])
def test_errors_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error: ")


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["bench", "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "--json" in out and "--size" in out and "--rays-in-flight" in out


@pytest.mark.slow
def test_default_frame_utilization():
    """The default 256 x 256 bunny frame on "rtl" with the default ray pool keeps the datapath
    >= 98 % busy, and the replay reproduces every response."""
    from driver import rtunit
    from driver.scenes.camera import primary_rays
    from driver.scenes.scene import load_scene
    from driver.tracer import trace
    scene = load_scene("bunny")
    o, d = primary_rays(scene.camera, 256, 256)
    res = trace(scene.mesh, o, d, backend="rtl", rays_in_flight=rtunit.DEFAULT_RAYS_IN_FLIGHT)
    s = res.stats
    assert s["rays"] == 65536 and s["replay_datapath"] == "timing"
    assert s["utilization"] >= 0.98 and s["wavefront_utilization"] >= 0.98


def test_memory_object(doc):
    """The default frame replayed with the node cache and memory."""
    m = doc["frame"]["rtunit_memory"]
    for k in ("hit_rate", "bytes_per_ray", "cycles", "utilization", "line_misses"):
        assert k in m, k
    assert m["replay_datapath"] == "timing" and 0 < m["hit_rate"] < 1
    assert m["cycles"] > doc["frame"]["rtunit"]["cycles"]       # fetches cost time, never less
    assert m["bytes_per_ray"] * doc["frame"]["rays"] == 64 * m["line_misses"]


def test_no_cache_reads_every_node_from_memory(tmp_path):
    """--cache-kib 0: no node cache; every line of every node fetch comes from memory, so the
    bytes from memory are the frame's node bytes rounded up to whole lines, and the replay is
    slower than with the default 32 KiB cache."""
    out = {k: tmp_path / f"{k}.json" for k in (0, 32)}
    for kib, path in out.items():
        assert main(["bench", "--size", "8", "--json", str(path), "--pyverilator-requests", "0",
                     "--sweep-size", "0", "--repeat", "1", "--cache-kib", str(kib),
                     "--ideal-replay", "--no-progress"]) == 0
    f0, f32 = (json.loads(out[k].read_text())["frame"] for k in (0, 32))
    m = f0["rtunit_memory"]
    assert m["replay_datapath"] == "timing" and m["line_hits"] == 0 and m["hit_rate"] == 0
    assert m["bytes_from_memory"] == 64 * m["line_accesses"] >= f0["node_bytes_fetched"]
    assert m["cycles"] > f32["rtunit_memory"]["cycles"] > f0["rtunit"]["cycles"]


def test_culled_stack_and_fill_in_the_bench(tmp_path, doc):
    """--cull-stack and --bvh-fill reach every trace of the run: the frame has fewer box ops and
    the same hits, the golden check and the replays still agree bit for bit, less memory
    traffic per ray."""
    out = tmp_path / "b.json"
    assert main(["bench", "--size", "16", "--json", str(out), "--pyverilator-requests", "0",
                 "--sweep-rays", "1,16", "--sweep-pipelines", "1", "--repeat", "1",
                 "--cull-stack", "--bvh-fill", "40", "--no-progress"]) == 0
    d = json.loads(out.read_text())
    f, base = d["frame"], doc["frame"]
    pt = d["provenance"]["design_point"]
    assert pt["cull_stack"] is True and pt["bvh_fill"] == 40 and f["bvh"]["fill"] == 40
    assert f["bvh"]["box_nodes"] < base["bvh"]["box_nodes"]
    assert f["stack_culls"] > 0 and f["box_ops"] < base["box_ops"]
    assert f["hits"] == base["hits"] and d["golden_matches_rtl"] is True
    assert f["embree"]["hit_mismatch"] == 0 and f["rtunit_memory"]["replay_datapath"] == "timing"
    assert f["rtunit_memory"]["bytes_per_ray"] < base["rtunit_memory"]["bytes_per_ray"]
    pt = doc["provenance"]["design_point"]
    assert pt["cull_stack"] is False and pt["bvh_fill"] == 0


def test_workload_bench_per_ray_type(tmp_path, capsys):
    out = tmp_path / "w.json"
    assert main(["bench", "--scene", "bunny_floor", "--workload", "path", "--size", "12",
                 "--bounces", "1", "--sweep-rays", "1,16", "--json", str(out),
                 "--ideal-replay", "--no-progress"]) == 0
    d = json.loads(out.read_text())
    f = d["frame"]
    assert d["provenance"]["design_point"]["workload"] == "path"
    assert set(f["by_type"]) == {"primary", "shadow", "bounce1"}
    assert [p["rays_in_flight"] for p in d["sweep"]] == [1, 16]
    assert all(set(p["by_type"]) == set(f["by_type"]) for p in d["sweep"])
    assert f["ops"] == sum(t["ops"] for t in f["by_type"].values())
    sh = f["by_type"]["shadow"]
    assert 0 < sh["any_hit_vs_closest_ops"] <= 1                 # any hit never issues more
    for t in f["by_type"].values():
        assert set(COUNTS + TIMING) <= set(t)
        assert t["rtunit"]["replay_datapath"] == "timing"
        # one kernel: a ray type's rays share the pipelines, so it has latency, not cycles
        assert t["rtunit_memory"]["cycles"] is None
        assert t["rtunit_memory"]["latency_mean"] >= t["rtunit"]["latency_mean"] > 0
    for key in ("rtunit", "rtunit_memory"):
        assert f[key]["ops"] == f["ops"] and f[key]["cycles"] >= f["ops"]
    assert f["rtunit_memory"]["cycles"] > f["rtunit"]["cycles"]
    assert f["embree"]["hit_mismatch"] == 0
    assert (tmp_path / "w_rtunit.png").stat().st_size > 1000
    assert "anyhit/closest" in capsys.readouterr().out


def test_workload_bench_one_timing_replay_by_default(tmp_path, monkeypatch, capsys):
    """Each request is simulated twice by default: the functional pass and one replay of the
    design point (the free-fetch replay and the rays-in-flight sweep are opt-in)."""
    import driver.rtunit.gpu as gpu
    calls = []
    real = gpu.replay_frame
    monkeypatch.setattr(gpu, "replay_frame", lambda *a, **k: calls.append(a[3]) or real(*a, **k))
    out = tmp_path / "w.json"
    assert main(["bench", "--scene", "sphere", "--workload", "shadow", "--size", "8",
                 "--json", str(out), "--no-progress"]) == 0
    d = json.loads(out.read_text())
    assert len(calls) == 1 and calls[0] is not None          # one replay, with its memory
    assert d["frame"]["rtunit"] is None and d["sweep"] is None
    assert d["frame"]["rtunit_memory"]["replay_datapath"] == "timing"
    # the default plot --help promises (it was drawn only with --plot or --sweep-rays): the
    # rays each RT unit holds, from the same replay
    assert d["plot"] == str(tmp_path / "w_rtunit.png")
    assert (tmp_path / "w_rtunit.png").stat().st_size > 1000
    # a one-kernel frame has no utilization per ray type: the table says so instead of a blank
    out = capsys.readouterr().out
    row = next(ln.split() for ln in out.splitlines() if ln.split()[:1] == ["shadow"])
    assert row[5] == "-" and "nan" not in out
    util = d["frame"]["rtunit_memory"]["utilization"]
    assert (f"util: one-kernel frame: its ray types share the pipelines, so none has cycles or "
            f"a utilization of its own (-); the frame's is {util:.3f}") in out


@pytest.mark.parametrize("workload", ["primary", "ao"])
def test_sweep_size_zero_means_no_sweep_in_every_mode(workload, tmp_path, monkeypatch):
    """--sweep-size 0 ran the workload bench's rays-in-flight sweep anyway (44 replays)."""
    import driver.rtunit.gpu as gpu
    replays = []
    real = gpu.replay_frame
    monkeypatch.setattr(gpu, "replay_frame", lambda *a, **k: replays.append(1) or real(*a, **k))
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "w.json"
    assert main(["bench", "--scene", "sphere", "--workload", workload, "--size", "8",
                 "--sweep-size", "0", "--sweep-rays", "4,8", "--plot", "p.png",
                 "--pyverilator-requests", "0", "--repeat", "1",
                 "--json", str(out), "--no-progress"]) == 0
    d = json.loads(out.read_text())
    assert not d.get("sweep") and not d.get("rtunit_sweep") and not d.get("plot")
    assert len(replays) == 1                          # the frame's replay, no sweep
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.json"]      # no plot


def test_workers_bench_builds_the_model_before_timing(monkeypatch):
    """A cold build cache must not land in the one-process time (it did: 54 s vs 1.2 s)."""
    import driver.backends.build as build
    import driver.bench as bench
    import driver.tiles as tiles
    calls = []
    real = build.build_harness
    monkeypatch.setattr(build, "build_harness", lambda p: calls.append(("build", p)) or real(p))

    class Timed(Exception):
        pass

    def render(*a, **k):
        calls.append(("render",))
        raise Timed

    monkeypatch.setattr(tiles, "render_tiles", render)
    with pytest.raises(Timed):
        bench.bench_workers(DesignPoint(scene="cornell", size=8), 2, 8, progress=False)
    assert calls[0][0] == "build" and calls[1] == ("render",)
    assert calls[0][1] == tiles._backend("rtl").params      # the model the tiles will load


def test_workers_bench_is_identical(tmp_path):
    out = tmp_path / "k.json"
    assert main(["bench", "--workers", "2", "--scene", "bunny_floor", "--workload", "ao",
                 "--size", "16", "--tile", "8", "--json", str(out), "--no-progress"]) == 0
    d = json.loads(out.read_text())
    assert d["identical"] and d["tiles"] == 4 and d["speedup"] > 0
    ph = d["phases_n_workers"]
    assert set(ph) == {"start_s", "first_tile_s", "tiles_s", "close_s"}
    assert all(v >= 0 for v in ph.values())
    assert sum(ph.values()) == pytest.approx(d["wall_s_n_workers"], abs=0.05)
    assert d["speedup_tiles"] > 0
    assert not list(tmp_path.glob("*.png"))


def test_end_to_end_runs_the_render_in_fresh_processes(tmp_path, capsys):
    """--end-to-end: a first run, then --repeat counted runs, each its own process; the rays per
    second are the frame's rays over the render's time outside the BVH."""
    out = tmp_path / "e.json"
    assert main(["bench", "--end-to-end", "--scene", "cornell", "--workload", "ao", "--size",
                 "16", "--repeat", "2", "--json", str(out), "--no-progress"]) == 0
    doc = json.loads(out.read_text())
    assert doc["provenance"]["design_point"]["size"] == 16
    assert doc["command"].startswith("rayflex render cornell --workload ao --size 16")
    runs = doc["runs"]
    assert len(runs) == 2 and doc["first_run"]["rays"] == runs[0]["rays"] == runs[1]["rays"]
    for r in runs:
        assert r["rays"] > 16 * 16 and r["trace_s"] == pytest.approx(r["wall_s"] - r["bvh_s"])
        assert r["rays_per_s"] == pytest.approx(r["rays"] / r["trace_s"])
        assert r["verdicts"]["datapath_wrong"] == 0 and r["replay_datapath"] == "timing"
        assert 0 < r["functional_s"] < r["trace_s"] < r["process_s"]
    med = doc["summary"]["rays_per_s"]
    assert med["min"] <= med["median"] <= med["max"]
    assert med["median"] == pytest.approx(sum(r["rays_per_s"] for r in runs) / 2)
    assert "rays per second outside loading and the BVH: median" in capsys.readouterr().out


def test_end_to_end_on_the_rt_unit(tmp_path, capsys):
    """--end-to-end --backend rtunit: the render on the RT unit in RTL, each run a fresh
    process; the unit's cycles instead of the replay's time."""
    out = tmp_path / "u.json"
    assert main(["bench", "--end-to-end", "--scene", "cornell", "--workload", "ao", "--size",
                 "8", "--repeat", "1", "--backend", "rtunit", "--rays-in-flight", str(SUITE_RAYS),
                 "--unit-check", "none", "--json", str(out), "--no-progress"]) == 0
    doc = json.loads(out.read_text())
    assert doc["backend"] == "rtunit"
    assert doc["command"].endswith("--check-embree --backend rtunit --unit-check none")
    (run,) = doc["runs"]
    assert run["unit_cycles"] > 0 and run["replay_s"] is None and run["traversal_mismatches"] is None
    assert run["verdicts"]["datapath_wrong"] == 0 and 0 < run["functional_s"] < run["trace_s"]
    assert doc["summary"]["replay_s"] is None
    assert doc["summary"]["rays_per_s"]["median"] == pytest.approx(run["rays_per_s"])
    assert "the RT unit" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [["--backend", "rtunit"], ["--backend", "golden", "--end-to-end"],
                                  ["--end-to-end", "--unit-check", "none"]])
def test_bench_takes_the_rt_unit_with_end_to_end_only(argv, capsys):
    assert main(["bench", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error:")


@pytest.mark.parametrize("extra", [["--bvh"], ["--workers", "2"], ["--repeat", "0"]])
def test_end_to_end_refuses_other_modes(extra, capsys):
    assert main(["bench", "--end-to-end", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error:")
