"""``rayflex sweep``: a grid of design points, rows equal to single-point benches, resume after an
interruption, the same rows on Dask workers, outputs and errors."""

from __future__ import annotations

import csv
import json

import pytest
from PIL import Image

from driver import sweep as sweep_mod
from driver.bench import bench_workload
from driver.cli import main
from driver.design import DesignPoint
from support.prebuild import SUITE_DEPTH, SUITE_RAYS

GRID = ["--scene", "sphere", "--workload", "ao", "--size", "10",
        "--config", "baseline-unified,baseline-disjoint", "--rays-in-flight", "4,32",
        "--cache-kib", "0,16"]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    assert main(["sweep", *GRID, "--csv", str(d / "s.csv"), "--json", str(d / "s.json"),
                 "--plot", str(d / "s.png"), "--ideal-replay", "--no-progress"]) == 0
    return d, json.loads((d / "s.json").read_text())


def test_grid_rows_and_outputs(swept):
    d, doc = swept
    assert len(doc["points"]) == 8
    assert doc["grid"] == {"config": ["baseline-unified", "baseline-disjoint"],
                           "rays_in_flight": [4, 32], "cache_kib": [0, 16]}
    assert doc["bit_exact"] == {"baseline-disjoint": True, "baseline-unified": True}
    assert len(doc["functional"]) == 1                  # traced once for every RT-unit point
    kinds = set(doc["functional"][0]["by_type"])
    assert kinds == {"primary", "ao"}
    with open(d / "s.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 8 * len(kinds)
    assert {(r["config"], r["rays_in_flight"], r["cache_kib"], r["ray_type"]) for r in table} \
        == {(c, r, k, t) for c in ("baseline-unified", "baseline-disjoint") for r in ("4", "32")
            for k in ("0", "16") for t in kinds}
    for e in doc["points"]:
        dp = e["design_point"]
        # the traced configuration replays as its timing (null), every other one on its RTL
        for key in ("rtunit", "rtunit_memory"):
            r = e[key]
            assert r["responses_verified"] is (None if r["replay_datapath"] == "timing" else True)
            assert (r["replay_datapath"] == "timing") == (dp["config"] == doc["traced_on"])
        assert e["ops"] == sum(t["ops"] for t in e["by_type"].values())
        assert e["rtunit"]["ops"] == e["ops"] == e["rtunit_memory"]["ops"]
        # a one-kernel frame: the ray types share the pipelines, so only the frame has cycles
        assert dp["frame_schedule"] == "one-kernel"
        assert all(t["rtunit"]["cycles"] is None and t["rtunit_memory"]["latency_mean"] > 0
                   for t in e["by_type"].values())
        if dp["cache_kib"]:
            assert e["rtunit_memory"]["cycles"] > e["rtunit"]["cycles"]
            assert 0 < e["rtunit_memory"]["hit_rate"] < 1
        else:                       # no cache: every node fetch from memory, no hit
            m = e["rtunit_memory"]
            assert m["hit_rate"] == 0 and m["line_misses"] == m["line_accesses"] > 0
            assert m["cycles"] > e["rtunit"]["cycles"]
        for t in e["by_type"].values():
            assert t["energy_per_ray"]["signals"] > 0 and t["energy_per_ray"]["memory_pj"] > 0
    # the same ops and cycles on both configurations (their responses were checked bit for bit)
    by = {(e["design_point"]["config"], e["design_point"]["rays_in_flight"],
           e["design_point"]["cache_kib"]): e for e in doc["points"]}
    for r in (4, 32):
        for k in (0, 16):
            a, b = by["baseline-unified", r, k], by["baseline-disjoint", r, k]
            assert a["rtunit"]["cycles"] == b["rtunit"]["cycles"]
            assert a["rtunit_memory"]["cycles"] == b["rtunit_memory"]["cycles"]
        # node fetches cost energy: no cache moves every node from DRAM
        assert by["baseline-unified", r, 0]["energy_per_ray"]["memory_pj"] > \
            by["baseline-unified", r, 16]["energy_per_ray"]["memory_pj"]
    with Image.open(d / "s.png") as im:
        assert im.format == "PNG" and im.size[0] > 600
    assert (d / "s.points.jsonl").is_file()


@pytest.mark.parametrize("which", [0, 7])
def test_rows_equal_single_point_benches(swept, which):
    """Every sweep point's cycles are those of ``bench`` run on that point alone."""
    _, doc = swept
    e = doc["points"][which]
    point = DesignPoint(**e["design_point"])
    b = bench_workload(point, sweep_rays=(), progress=False, ideal=True)
    assert e["rtunit"]["cycles"] == b["frame"]["rtunit"]["cycles"]
    assert e["rtunit_memory"]["cycles"] == b["frame"]["rtunit_memory"]["cycles"]
    for kind, t in e["by_type"].items():
        ref = b["frame"]["by_type"][kind]
        assert t["ops"] == ref["ops"]
        for key in ("rtunit", "rtunit_memory"):
            assert t[key]["latency_mean"] == ref[key]["latency_mean"]


def test_interrupted_sweep_resumes(tmp_path, monkeypatch):
    points = [DesignPoint(scene="sphere", workload="primary", size=8, rays_in_flight=r,
                          cache_kib=0) for r in (1, 2, 4, 8)]
    results = tmp_path / "r.points.jsonl"
    real = sweep_mod.measure_point
    calls = []

    def interrupted(p, *args):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(p)
        return real(p, *args)

    monkeypatch.setattr(sweep_mod, "measure_point", interrupted)
    with pytest.raises(KeyboardInterrupt):
        sweep_mod.sweep(points, results=results, progress=False)
    assert len(results.read_text().splitlines()) == 2
    calls.clear()
    monkeypatch.setattr(sweep_mod, "measure_point", lambda p, *args: calls.append(p)
                        or real(p, *args))
    doc = sweep_mod.sweep(points, results=results, progress=False)
    assert calls == points[2:]                          # only the points not done before
    fresh = sweep_mod.sweep(points, progress=False)
    assert [e["rtunit_memory"]["cycles"] for e in doc["points"]] == \
        [e["rtunit_memory"]["cycles"] for e in fresh["points"]]
    assert all(e["rtunit"] is None for e in doc["points"])    # one timing replay by default


def test_points_on_dask_workers_equal_one_process(tmp_path):
    points = [DesignPoint(scene="sphere", workload="shadow", size=8, rays_in_flight=r)
              for r in (2, 16)]
    one = sweep_mod.sweep(points, progress=False, ideal=True)
    two = sweep_mod.sweep(points, workers=2, progress=False, ideal=True)
    for a, b in zip(one["points"], two["points"]):
        assert a["design_point"] == b["design_point"]
        for key in ("rtunit", "rtunit_memory"):
            assert a[key]["cycles"] == b[key]["cycles"]


@pytest.mark.parametrize("argv", [
    ["--csv", "s.txt"],
    ["--results", "r.txt"],
    ["--config", "all,x"],
    ["--cache-kib", "1", "--cache-ways", "64"],
    ["--workers", "0"],
    ["--size", "0"],
    ["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"],   # was accepted, failed 5 s later
    ["--backend", "rtunit", "--rt-units", "1,2"],             # the unit is one RT unit
    ["--backend", "rtunit", "--stack-depth", "1"],            # a depth the RTL cannot build
    ["--backend", "rtunit", "--bvh-format", "q8g"],           # a format the unit cannot read
])
def test_errors_before_any_work(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sweep_mod, "trace_workload", lambda *a: pytest.fail("traced"))
    monkeypatch.setattr(sweep_mod, "sweep", lambda *a, **k: pytest.fail("started the sweep"))
    assert main(["sweep", "--scene", "sphere", "--no-progress", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error: "), err
    assert not list(tmp_path.iterdir())


def test_the_build_notice_counts_only_models_really_missing(swept):
    """Once the sweep has run, every model it uses is cached: the notice named the traced models
    by the harness's parameters (rayflex_power_e0_d0_c0_t0_l11, cached as
    rayflex_power_e0_d0_l11) and announced "2 of 4 models to build first" on every sweep."""
    from driver.cli import build_parser, options
    from driver.power import uncached_models
    points = options.grid_from_args(build_parser().parse_args(["sweep", *GRID]))
    models = sweep_mod.models(points)
    assert sorted(kind for kind, _ in models) == ["rtl", "rtl", "signals", "signals"]
    assert uncached_models(models) == []


def test_the_table_marks_a_missing_value_as_bench_does(swept):
    """The sweep table printed ``nan`` where bench left blanks: both print ``-``
    (``driver.core.words.cell``) for a ray type's utilization in a one-kernel frame."""
    _, doc = swept
    rows = [ln.split() for ln in sweep_mod.table(doc).splitlines()[1:-1]]
    assert len(rows) == 8 * 3 and "nan" not in sweep_mod.table(doc)
    for r in rows:
        util, ideal = r[6], r[7]       # after the 3 varied options, type, rays and ops/ray
        assert (util == ideal == "-") == (r[3] != "all"), r


def test_points_through_the_rt_unit_in_rtl(tmp_path):
    """``--backend rtunit``: every point's frame also runs through the RT unit in RTL with the
    point's ray slots, stack depth and memory; every ray agrees with the traversal, the replay
    with the unit's costs counts its cycles; a results file of points measured without the
    unit is measured again."""
    argv = ["sweep", "--scene", "sphere", "--workload", "ao", "--size", "8",
            "--rays-in-flight", str(SUITE_RAYS), "--stack-depth", str(SUITE_DEPTH),
            "--cache-kib", "0,16",
            "--csv", str(tmp_path / "u.csv"), "--json", str(tmp_path / "u.json"), "--no-progress"]
    assert main(argv[:-5] + ["--json", str(tmp_path / "u.json"), "--no-progress"]) == 0
    assert all("unit_rtl" not in e for e in json.loads((tmp_path / "u.json").read_text())
               ["points"])
    assert main([*argv, "--backend", "rtunit"]) == 0
    doc = json.loads((tmp_path / "u.json").read_text())
    assert doc["bit_exact"] == {"baseline-unified": True}
    uncached, cached = (e["unit_rtl"] for e in doc["points"])
    assert [e["design_point"]["cache_kib"] for e in doc["points"]] == [0, 16]
    for u in (uncached, cached):
        assert (u["rays_in_flight"], u["stack_depth"]) == (SUITE_RAYS, SUITE_DEPTH)
        assert u["traversal_mismatches"] == 0 and u["cycles"] > 0
        assert u["replay_cycles_ratio"] == pytest.approx(1, abs=0.01)
    assert uncached["cycles"] > cached["cycles"]          # every node from DRAM without a cache
    with open(tmp_path / "u.csv") as f:
        rows = list(csv.DictReader(f))
    assert {int(r["unit_rtl_cycles"]) for r in rows} == {uncached["cycles"], cached["cycles"]}
