"""``rayflex suite`` (driver/suite.py): LumiBench's runs from a tiny root the test writes, a
TOML suite, files per run, the summary, resuming an interrupted suite, Dask workers; and, slow,
the 12 runs the shared LumiBench scenes allow."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from driver.cli import main
from driver.suite import SuiteError, lumibench_runs, read_suite
from driver.suite_report import ROW_KEYS
from test_lumibench_scenes import suite_root

SHARED = Path(__file__).resolve().parents[2] / "shared" / "scenes" / "lumibench"


@pytest.fixture
def root(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_SCENE_CACHE", str(tmp_path / "cache"))
    return suite_root(tmp_path / "lumi")


def suite(*argv) -> int:
    return main(["suite", *argv, "--backend", "golden", "--no-progress"])


def test_lumibench_runs_are_what_the_root_allows(root):
    runs, skipped = lumibench_runs(root)
    assert [r.name for r in runs] == ["SHIP_PT", "SHIP_SH", "SHIP_AO", "BATH_PT", "BATH_SH",
                                      "BATH_AO"]
    assert runs[0].scene == "lumibench:SHIP" and runs[0].workload == "lumibench-pt"
    assert (runs[0].size, runs[0].spp) == (128, 2)
    assert "procedural" in skipped["WKND"] and "not in" in skipped["SPRNG"]
    assert len(skipped) == 16 - 2
    runs, _ = lumibench_runs(root, ["bath"], ["ao", "SH"])
    assert [r.name for r in runs] == ["BATH_SH", "BATH_AO"]
    with pytest.raises(SuiteError, match="unknown shader"):
        lumibench_runs(root, None, ["xx"])


def test_suite_writes_each_run_and_a_summary_and_resumes(root, in_tmp, capsys):
    argv = ["lumibench", "--lumibench-root", str(root), "--scenes", "BATH,SHIP", "--workloads",
            "ao,sh", "--size", "12", "--out", "out"]
    assert suite(*argv) == 0
    out = in_tmp / "out"
    names = ["BATH_SH", "BATH_AO", "SHIP_SH", "SHIP_AO"]          # in the order asked for
    for n in names:
        doc = json.loads((out / f"{n}.json").read_text())
        assert doc["run"]["name"] == n and doc["width"] == 12
        assert doc["rtunit_memory"]["replay_datapath"] == "timing" and doc["rtunit"] is None
        assert doc["embree"]["rays_compared"] == doc["rays"]
        assert doc["embree"]["adjudicated"]["classes"]["datapath_wrong"] == 0
        assert set(doc["by_type"]) == {"primary", n.endswith("AO") and "ao" or "shadow"}
        assert (out / f"{n}.png").stat().st_size > 0
    assert json.loads((out / "BATH_AO.json").read_text())["lumibench"]["partial"] is False
    summary = json.loads((out / "summary.json").read_text())
    assert [r["name"] for r in summary["runs"]] == names and summary["runs_made"] == 4
    assert summary["totals"]["rays"] == sum(r["rays"] for r in summary["runs"])
    assert all(r["energy_per_ray_signals"] > 0 and 0 < r["utilization_memory"] <= 1
               for r in summary["runs"])
    csv = (out / "summary.csv").read_text().splitlines()
    assert csv[0].split(",") == list(ROW_KEYS) and len(csv) == 5
    assert (out / "summary.png").stat().st_size > 0
    printed = capsys.readouterr().out
    assert "BATH_AO" in printed and "4 made now" in printed
    # again: nothing to make; a run whose files went missing is made again, alone
    mtime = (out / "SHIP_SH.json").stat().st_mtime_ns
    (out / "BATH_AO.json").unlink()
    assert suite(*argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs_made"] == 1 and len(summary["runs"]) == 4
    assert (out / "SHIP_SH.json").stat().st_mtime_ns == mtime
    # another design point is another result: every run is made again
    assert suite(*argv, "--cache-kib", "16") == 0
    assert json.loads((out / "summary.json").read_text())["runs_made"] == 4
    assert not [p for p in out.iterdir() if p.name.startswith(".")]       # no temporary files


def test_a_toml_suite_of_any_scenes(root, in_tmp):
    (in_tmp / "mine.toml").write_text(
        'name = "mine"\nsize = 10\nspp = 1\n'
        '[[runs]]\nscene = "sphere"\nworkload = "lumibench-ao"\n'
        '[[runs]]\nname = "bunny_path"\nscene = "bunny"\nworkload = "path"\nbounces = 1\n')
    name, runs = read_suite(in_tmp / "mine.toml")
    assert name == "mine" and [r.name for r in runs] == ["sphere_AO", "bunny_path"]
    assert suite("--suite", "mine.toml", "--out", "o") == 0
    summary = json.loads((in_tmp / "o" / "summary.json").read_text())
    assert [r["workload"] for r in summary["runs"]] == ["lumibench-ao", "path"]
    assert json.loads((in_tmp / "o" / "bunny_path.json").read_text())["width"] == 10


@pytest.mark.parametrize("toml, words", [
    ("[[runs]]\nscene = 'sphere'\n", "needs scene and workload"),
    ("x = 1\n[[runs]]\nscene = 'sphere'\nworkload = 'ao'\n", "unknown key"),
    ("[[runs]]\nscene = 'sphere'\nworkload = 'ao'\n[[runs]]\nscene = 'sphere'\nworkload = 'ao'\n",
     "two runs named"),
    ("[[runs]]\nscene = 'nope'\nworkload = 'ao'\n", "unknown scene"),
    ("[[runs]]\nscene = 'sphere'\nworkload = 'nope'\n", "unknown value"),
])
def test_a_bad_suite_is_one_line_before_any_work(in_tmp, error_line, toml, words):
    (in_tmp / "bad.toml").write_text(toml)
    assert suite("--suite", "bad.toml", "--out", "o") == 2
    assert words in error_line()
    assert not (in_tmp / "o").exists()


def test_a_suite_neither_named_nor_given_says_what_to_give(in_tmp, error_line):
    """With neither NAME nor --suite the line said "..., not both"."""
    assert suite() == 2
    assert error_line() == ("rayflex: error: which suite? give a built-in suite's name "
                            "(lumibench: rayflex suite lumibench) or a TOML list of runs "
                            "(--suite FILE)")
    (in_tmp / "s.toml").write_text("[[runs]]\nscene = 'sphere'\nworkload = 'ao'\n")
    assert suite("lumibench", "--suite", "s.toml") == 2
    assert error_line() == ("rayflex: error: give the suite once: lumibench or --suite s.toml, "
                            "not both")
    assert not list(in_tmp.glob("suite-*"))


def test_runs_on_dask_workers_equal_one_process(root, in_tmp):
    argv = ["lumibench", "--lumibench-root", str(root), "--scenes", "SHIP", "--workloads",
            "ao,pt", "--size", "8"]
    assert suite(*argv, "--out", "one") == 0
    assert suite(*argv, "--out", "two", "--workers", "2") == 0
    for n in ("SHIP_AO", "SHIP_PT"):
        a, b = (json.loads((in_tmp / d / f"{n}.json").read_text()) for d in ("one", "two"))
        for k in ("rays", "hits", "ops", "box_ops", "tri_ops"):
            assert a[k] == b[k]
        assert a["rtunit_memory"]["cycles"] == b["rtunit_memory"]["cycles"]
        assert (in_tmp / "one" / f"{n}.png").read_bytes() == (in_tmp / "two" / f"{n}.png"
                                                                ).read_bytes()


@pytest.mark.slow
@pytest.mark.skipif(not (Path(os.environ.get("LUMIBENCH_ROOT", SHARED)) / "Scenes").is_dir(),
                    reason="needs a LumiBench repository (LUMIBENCH_ROOT)")
def test_the_lumibench_runs_of_the_shared_scenes_on_the_rtl(tmp_path):
    """Every run the shared partial copy allows (BATH, SPRNG, LANDS, SHIP x PT, SH, AO), on the
    RTL with every ray checked and replayed: no ray where the datapath is wrong."""
    lroot = os.environ.get("LUMIBENCH_ROOT", str(SHARED))
    code = main(["suite", "lumibench", "--lumibench-root", lroot, "--out", str(tmp_path),
                 "--workers", "2", "--no-progress"])
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert code == 0 and summary["datapath_wrong"] == 0
    assert len(summary["runs"]) == 12


def test_every_key_the_suite_writes_is_documented(root, in_tmp):
    from test_statistics_doc import documented, emitted
    assert suite("lumibench", "--lumibench-root", str(root), "--scenes", "BATH", "--workloads",
                 "sh", "--size", "8", "--out", "o") == 0
    assert main(["bench", "--scene-load", "--lumibench-root", str(root), "--scene",
                 "lumibench:BATH", "--json", "load.json", "--no-progress"]) == 0
    keys, maps = documented()
    docs = {"run": json.loads((in_tmp / "o" / "BATH_SH.json").read_text()),
            "summary": json.loads((in_tmp / "o" / "summary.json").read_text()),
            "scene-load": json.loads((in_tmp / "load.json").read_text())}
    missing = {k: f"{name}: {path}" for name, doc in docs.items()
               for k, path in emitted(doc, maps) if k not in keys}
    assert not missing, f"not in docs/statistics.md: {missing}"
    header = (in_tmp / "o" / "summary.csv").read_text().splitlines()[0].split(",")
    text = Path(__file__).resolve().parents[1].joinpath("docs", "statistics.md").read_text()
    assert all(f"`{h}`" in text for h in header)


def test_a_suite_of_one_run_spreads_its_tiles_over_the_workers(root, in_tmp, monkeypatch):
    import driver.suite
    monkeypatch.setattr(driver.suite, "SPLIT_TILE", 8)          # 9 tiles of the 24 x 24 frame
    argv = ["lumibench", "--lumibench-root", str(root), "--scenes", "BATH", "--workloads", "ao",
            "--size", "24"]
    assert suite(*argv, "--out", "one") == 0
    assert suite(*argv, "--out", "two", "--workers", "2") == 0
    a, b = (json.loads((in_tmp / d / "BATH_AO.json").read_text()) for d in ("one", "two"))
    for k in ("rays", "hits", "ops", "box_ops", "tri_ops"):
        assert a[k] == b[k]
    assert a["embree"]["adjudicated"]["classes"] == b["embree"]["adjudicated"]["classes"]
    assert len(b["workers_peak_rss_bytes"]) == 2 and "workers_peak_rss_bytes" not in a
    assert b["tile"] == 8 and a["tile"] == 24
    assert (in_tmp / "one" / "BATH_AO.png").read_bytes() == (in_tmp / "two" / "BATH_AO.png"
                                                              ).read_bytes()


def test_the_lumibench_page_quotes_its_json():
    """docs/lumibench.md's generated sections (the table of runs, the text that quotes numbers)
    are what tools/figures.py makes from the JSON files as they are."""
    from test_docs import ROOT, _figures
    page = (ROOT / "docs" / "lumibench.md").read_text()
    assert _figures().lumibench_page() == page, "run python tools/figures.py --lumibench-page"
    assert "<!-- generated: table" in page and "| SHIP_AO |" in page


def test_runs_through_the_rt_unit_share_their_camera_rays_batch(root, in_tmp):
    """Through the RT unit in RTL, a scene's runs trace the same camera rays first: the second
    run reuses the first's batch (``unit_rtl.reused_batches``), with the statistics and results
    of that run made alone, bit for bit; the shared batches are removed when every run is made."""
    from support.prebuild import SUITE_DEPTH, SUITE_RAYS
    argv = ["suite", "lumibench", "--lumibench-root", str(root), "--scenes", "BATH",
            "--size", "8", "--spp", "1", "--backend", "rtunit", "--flatten",
            "--rays-in-flight", str(SUITE_RAYS), "--stack-depth", str(SUITE_DEPTH),
            "--no-progress"]
    assert main([*argv, "--workloads", "ao,sh", "--out", "both"]) == 0
    docs = {n: json.loads((in_tmp / "both" / f"BATH_{n}.json").read_text()) for n in ("AO", "SH")}
    reused = {n: d["by_type"]["primary"]["unit_rtl"]["reused_batches"] for n, d in docs.items()}
    assert sorted(reused.values()) == [0, 1]
    assert not (in_tmp / "both" / ".unit-batches").exists()
    second = next(n for n, r in reused.items() if r)
    assert main([*argv, "--workloads", second.lower(), "--out", "alone"]) == 0
    alone = json.loads((in_tmp / "alone" / f"BATH_{second}.json").read_text())
    got = docs[second]
    assert got["by_type"]["primary"]["unit_rtl"]["cycles"] > 0
    for doc in (got, alone):
        doc["unit_rtl"].pop("reused_batches")
        for t in doc["by_type"].values():
            t["unit_rtl"].pop("reused_batches")
    assert got["unit_rtl"] == alone["unit_rtl"] and got["embree"] == alone["embree"]
    assert got["by_type"].keys() == alone["by_type"].keys()
    for t in got["by_type"]:
        assert got["by_type"][t]["unit_rtl"] == alone["by_type"][t]["unit_rtl"]
    assert (in_tmp / "both" / f"BATH_{second}.png").read_bytes() == \
        (in_tmp / "alone" / f"BATH_{second}.png").read_bytes()


def test_render_refuses_a_lumibench_scene_on_the_rt_unit_before_loading_it(root, in_tmp,
                                                                           monkeypatch,
                                                                           error_line):
    """LumiBench's scenes are instanced: the RT unit in RTL without --transform datapath (or
    --flatten) is refused in one line before the scene is loaded."""
    import driver.scenes.scene as scene_mod

    def no_load(*a, **k):
        raise AssertionError("the scene was loaded before the refusal")
    monkeypatch.setattr(scene_mod, "load_scene", no_load)
    monkeypatch.setenv("LUMIBENCH_ROOT", str(root))
    assert main(["render", "lumibench:BATH", "--size", "8", "--backend", "rtunit",
                 "--no-progress"]) == 2
    assert "--transform datapath" in error_line()
    assert not list(in_tmp.glob("*.png"))
