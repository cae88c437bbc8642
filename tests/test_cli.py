"""The ``rayflex`` command line: render outputs, JSON statistics, one-line errors with exit 2."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

from driver.cli import main
COUNTS = ("rays", "hits", "box_ops", "tri_ops", "ops", "latency_cycles", "box_ops_per_ray",
          "tri_ops_per_ray", "node_bytes_fetched", "backend")
WAVEFRONT = ("cycles", "utilization", "sim_wall_s", "sim_cycles_per_s", "frame_us_at_1ghz")
EMBREE_KEYS = ("rays_compared", "hit_mismatch", "prim_mismatch", "edge_ties", "max_t_rel_err")


pytestmark = pytest.mark.usefixtures("in_tmp")      # every test in its own empty directory


def size_of(path):
    with Image.open(path) as im:
        assert im.format == "PNG"
        return im.size


def test_render_defaults_write_png_and_heatmap(capsys, in_tmp):
    assert main(["render", "sphere", "--size", "16", "--backend", "golden", "--no-progress"]) == 0
    assert size_of(in_tmp / "sphere.png") == (16, 16)
    assert size_of(in_tmp / "sphere_heatmap.png")[0] > 100
    out = capsys.readouterr().out
    assert "256 rays" in out and "cycles" in out and "BVH4" in out and "sphere.png" in out


def test_render_all_outputs_and_stats_json(capsys, in_tmp):
    rc = main(["render", "room", "--width", "20", "--height", "12", "--backend", "golden",
               "--check-embree", "--stats-json", "s.json", "--out", "img.png",
               "--heatmap", "hm.png"])
    assert rc == 0
    assert size_of(in_tmp / "img.png") == (20, 12)
    size_of(in_tmp / "hm.png")
    doc = json.loads((in_tmp / "s.json").read_text())
    assert set(COUNTS) <= set(doc) and set(WAVEFRONT) == set(doc["wavefront"])
    assert doc["provenance"]["design_point"]["config"] == "baseline-unified"
    assert doc["rays"] == 240 and doc["backend"] == "golden"
    assert doc["ops"] == doc["box_ops"] + doc["tri_ops"]
    assert set(EMBREE_KEYS) <= set(doc["embree"])
    assert doc["embree"]["hit_mismatch"] == 0 and doc["embree"]["prim_mismatch"] == 0
    assert {"box_nodes", "tri_nodes", "depth", "sah_cost", "build_s", "bytes"} <= set(doc["bvh"])
    assert doc["width"] == 20 and doc["height"] == 12 and doc["scene"] == "room"
    assert "embree:" in capsys.readouterr().out


def test_render_bunny_small(in_tmp):
    assert main(["render", "bunny", "--size", "32", "--backend", "golden", "--no-progress",
                 "--stats-json", "b.json"]) == 0
    assert size_of(in_tmp / "bunny.png") == (32, 32)
    assert json.loads((in_tmp / "b.json").read_text())["hits"] > 50


@pytest.mark.parametrize("tile", [[], ["--tile", "16"]], ids=["whole", "tiled"])
def test_render_fill_and_culled_stack(in_tmp, tile):
    """--bvh-fill shapes the tree and --cull-stack drops box requests: same image, fewer box ops,
    ``stack_culls`` in the statistics (tiled frames too)."""
    base = ["render", "bunny", "--size", "24", "--backend", "golden", "--no-progress", *tile]
    assert main(base + ["--json", "a.json", "--out", "a.png"]) == 0
    assert main(base + ["--json", "b.json", "--out", "b.png", "--cull-stack"]) == 0
    assert main(base + ["--json", "c.json", "--out", "c.png", "--bvh-fill", "40"]) == 0
    a, b, c = (json.loads((in_tmp / f"{k}.json").read_text()) for k in "abc")
    assert (in_tmp / "a.png").read_bytes() == (in_tmp / "b.png").read_bytes()
    assert "stack_culls" not in a and b["stack_culls"] > 0
    assert a["box_ops"] == b["box_ops"] + b["stack_culls"] and a["tri_ops"] == b["tri_ops"]
    assert a["hits"] == b["hits"] == c["hits"]
    assert a["bvh"]["fill"] == 0 and c["bvh"]["fill"] == 40
    assert c["bvh"]["box_nodes"] < a["bvh"]["box_nodes"]


def test_render_mesh_file_and_toml(in_tmp):
    import trimesh
    trimesh.creation.box().export(str(in_tmp / "cube.obj"))
    assert main(["render", "cube.obj", "--size", "8", "--backend", "golden", "--no-progress"]) == 0
    assert size_of(in_tmp / "cube.png") == (8, 8)
    (in_tmp / "mine.toml").write_text('mesh = "cube.obj"\nwidth = 10\nheight = 6\n')
    assert main(["render", "mine.toml", "--backend", "golden", "--no-progress"]) == 0
    assert size_of(in_tmp / "mine.png") == (10, 6)




@pytest.mark.parametrize("args, words", [
    (["render", "no_such_scene"], "unknown scene"),
    (["render", "missing.ply"], "no such file"),
    (["render", "sphere", "--size", "0"], "1..8192"),
    (["render", "sphere", "--size", "-5"], "1..8192"),
    (["render", "sphere", "--size", "100000"], "1..8192"),
    (["render", "sphere", "--width", "0"], "width"),
    (["render", "sphere", "--size", "8", "--width", "4"], "either"),
    (["render", "sphere", "--backend", "nope"], "unknown backend"),
    (["render", "sphere", "--out", "no/such/dir/x.png"], "directory"),
    (["render", "sphere", "--bvh-fill", "-1"], "--bvh-fill must be an integer >= 0"),
    (["render", "sphere", "--workers", "2", "--scheduler", "tcp://127.0.0.1:9"],
     "give one of them"),
])
def test_user_mistakes_exit_2_with_one_line(error_line, args, words):
    assert main(args + ["--backend", "golden"] * ("--backend" not in args)) == 2
    assert words in error_line()


@pytest.mark.parametrize("flags", [["--cull-stack"], ["--bvh-fill", "8"], ["--flatten"]])
def test_bench_bvh_refuses_tree_flags(error_line, flags):
    assert main(["bench", "--bvh", "--no-progress", *flags]) == 2
    assert "--bvh measures" in error_line()


def test_frame_too_big_for_memory_is_refused_at_once(error_line, monkeypatch):
    """Issue 11 #5: --size 8192 allocated > 15 GB and was killed by the kernel, no message."""
    import driver.render
    monkeypatch.setattr(driver.render, "available_memory", lambda: 1 * 2**30)
    assert main(["render", "sphere", "--size", "8192", "--backend", "golden"]) == 2
    assert "1.0 GiB available: use a smaller --size or --tile" in error_line()


def test_bad_files_exit_2(error_line, in_tmp):
    (in_tmp / "bad.ply").write_bytes(b"garbage\x00")
    assert main(["render", "bad.ply", "--backend", "golden"]) == 2
    assert "cannot read" in error_line()
    (in_tmp / "bad.toml").write_text('mesh = "sphere"\n[camera]\nposition = [0,0,0]\n'
                                     'look_at = [0,0,0]\n')
    assert main(["render", "bad.toml", "--backend", "golden"]) == 2
    assert "same point" in error_line()
    (in_tmp / "fov.toml").write_text('mesh = "sphere"\n[camera]\nposition = [0,5,0]\n'
                                     'look_at = [0,0,0]\nfov_deg = 0\n')
    assert main(["render", "fov.toml", "--backend", "golden"]) == 2
    assert "fov" in error_line()


@pytest.mark.parametrize("text, what", [
    ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", "2: vertex 2: coordinate 'x' is not a number"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
     "4: face 1: vertex index 7 is beyond the file's 3 vertices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n",
     "5: face 2 has 2 corners; a face needs at least 3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n",
     "3: vertex 3 has 2 coordinates; a vertex needs 3 (x y z)"),
])
def test_a_broken_obj_file_is_named_by_line_in_obj_terms(error_line, in_tmp, text, what):
    """A broken mesh answered in numpy's words ("string or file could not be read to its end
    due to unmatched data", "index 6 is out of bounds for axis 0 with size 3")."""
    (in_tmp / "m.obj").write_text(text)
    assert main(["render", "m.obj", "--backend", "golden", "--size", "4"]) == 2
    assert error_line() == f"rayflex: error: m.obj:{what}"
    assert not list(in_tmp.glob("*.png"))


def test_camera_inside_mesh_is_legal(in_tmp):
    (in_tmp / "in.toml").write_text('mesh = "sphere"\nsize = 6\n[camera]\n'
                                    'position = [0, 0, 0]\nlook_at = [1, 0, 0]\n')
    assert main(["render", "in.toml", "--backend", "golden", "--no-progress"]) == 0


def test_backend_that_cannot_be_built_exits_2(error_line, monkeypatch):
    import driver.backends

    def broken(name, **options):
        raise driver.BackendError(f"backend {name!r} cannot be built: verilator not found")
    monkeypatch.setattr(driver.backends, "backend", broken)
    assert main(["render", "sphere", "--size", "4", "--backend", "rtl"]) == 2
    assert "cannot be built" in error_line()


def test_argparse_errors_exit_2(capsys):
    for args in (["render", "sphere", "--size", "abc"], ["frobnicate"],
                 ["render", "sphere", "--bogus"], ["render", "sphere", "--latency", "x"]):
        with pytest.raises(SystemExit) as e:
            main(args)
        assert e.value.code == 2
    capsys.readouterr()
    assert main([]) == 2


def test_help(capsys):
    for args in (["--help"], ["render", "--help"]):
        with pytest.raises(SystemExit) as e:
            main(args)
        assert e.value.code == 0
    out = capsys.readouterr().out
    assert "render" in out and "--check-embree" in out and "--json" in out
    assert "--stats-json" not in out                       # the old spelling is a hidden alias


def test_help_names_exit_codes_and_environment(capsys):
    """Issue 11 #6: RAYFLEX_CACHE and RAYFLEX_PGO were not in --help; issue 12: one exit table."""
    from driver.cli import ENVIRONMENT, EXIT_CODES
    for args in (["--help"], ["render", "--help"], ["knn", "--help"], ["bench", "--help"]):
        with pytest.raises(SystemExit):
            main(args)
        out = capsys.readouterr().out
        assert "RAYFLEX_CACHE" in out and "RAYFLEX_PGO" in out and "~/.cache/rayflex" in out
        for code in EXIT_CODES:
            assert f"  {code} " in out, (args, code)
    assert set(EXIT_CODES) >= {0, 1, 2, 130, 143} and set(ENVIRONMENT) >= {"RAYFLEX_CACHE",
                                                                              "RAYFLEX_PGO"}


def test_version(capsys):
    """Issue 11 #6: --version was missing."""
    from importlib.metadata import version
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"rayflex {version('rayflex-driver')}"


@pytest.mark.parametrize("flag", ["--json", "--stats-json"])
def test_json_flag_and_old_spelling(in_tmp, flag):
    """Issue 12 #4: one spelling --json PATH; the old one still works."""
    assert main(["render", "sphere", "--size", "4", "--backend", "golden", "--no-progress",
                 flag, "s.json"]) == 0
    assert json.loads((in_tmp / "s.json").read_text())["rays"] == 16


# ---------------------------------------------------------------------------------------------
# outputs: checked before any work, written by extension, never overwritten by one another

def test_outputs_are_written_by_extension(in_tmp):
    """Issue 11 #3: --out x.jpg wrote PNG bytes into a .jpg."""
    assert main(["render", "sphere", "--size", "8", "--backend", "golden", "--no-progress",
                 "--out", "x.jpg", "--heatmap", "h.webp"]) == 0
    for name, fmt in (("x.jpg", "JPEG"), ("h.webp", "WEBP")):
        with Image.open(in_tmp / name) as im:
            assert im.format == fmt


@pytest.mark.parametrize("args, words", [
    (["--heatmap", "same.png", "--out", "same.png"], "same file as --out"),
    (["--json", "same.png", "--out", "same.png"], "extension"),
    (["--json", "x.json", "--heatmap", "./x.json"], "extension"),
    (["--out", "sub/../same.png", "--heatmap", "same.png"], "same file"),
    (["--out", "x.txt"], "unknown extension"),
    (["--out", "noext"], "unknown extension"),
    (["--json", "s.csv"], ".json"),
    (["--out", "adir"], "is a directory"),
    (["--out", "/proc/x.png"], "cannot write in /proc"),
    (["--json", "/proc/s.json"], "cannot write in /proc"),
])
def test_bad_outputs_fail_before_any_work(error_line, in_tmp, monkeypatch, args, words):
    """Issue 11 #3: a bad output path failed only after the whole render, or silently destroyed
    another output. Now: one line, exit 2, before the scene is even loaded, nothing written."""
    import driver.render
    (in_tmp / "adir").mkdir()
    (in_tmp / "sub").mkdir()
    (in_tmp / "same.png").write_bytes(b"keep me")

    def no_render(*a, **k):
        raise AssertionError("rendered before checking the outputs")
    monkeypatch.setattr(driver.render, "render", no_render)
    assert main(["render", "sphere", "--size", "8", "--backend", "golden", *args]) == 2
    assert words in error_line()
    assert (in_tmp / "same.png").read_bytes() == b"keep me"
    assert sorted(p.name for p in in_tmp.iterdir()) == ["adir", "same.png", "sub"]


def test_bare_scene_name_wins_over_a_local_file_and_says_so(capsys, in_tmp):
    """Issue 11 #6: a file or folder named bunny here shadowed the built-in scene silently."""
    (in_tmp / "sphere").mkdir()
    assert main(["render", "sphere", "--size", "4", "--backend", "golden", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "'sphere' is the scene" in err and "./sphere" in err
    assert (in_tmp / "sphere.png").is_file()


def test_console_script():
    exe = shutil.which("rayflex") or str(Path(sys.executable).parent / "rayflex")
    assert os.path.exists(exe), "the rayflex console script is not installed (pip install -e .)"
    r = subprocess.run([exe, "render", "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "--backend" in r.stdout
    r = subprocess.run([exe, "render", "no_such_scene", "--backend", "golden"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.strip().startswith("rayflex: error: unknown scene")
    assert len(r.stderr.strip().splitlines()) == 1


def test_one_name_for_the_cache_in_readme_help_and_code(capsys):
    """The README and --help named the cache differently (~/.cache/rayflex vs
    ~/.cache/rayflex/verilator); now RAYFLEX_CACHE is one folder holding every cache."""
    import re
    from pathlib import Path

    from driver import area
    from driver.backends import cache as verilate
    from driver.cli import ENVIRONMENT
    from driver.power import netlist
    default = re.search(r"\(default (\S+?)\)", ENVIRONMENT["RAYFLEX_CACHE"]).group(1)
    assert default == verilate.DEFAULT_CACHE == "~/.cache/rayflex"
    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    assert f"`{default}` (`RAYFLEX_CACHE`" in readme
    root = verilate.cache_root()
    assert [verilate.cache_dir(), area.cache_root(), netlist.cache_root()] == \
        [root / "verilator", root / "area", root / "power"]


def test_one_default_backend_for_the_api_and_the_command_line():
    """driver.trace defaulted to the rtl backend and driver.tracer.trace to golden."""
    import inspect

    import driver
    from driver import knn, render, tiles, tracer
    from driver.backends import DEFAULT_BACKEND
    from driver.cli import build_parser
    defaults = {f.__module__ + "." + f.__name__: inspect.signature(f).parameters["backend"].default
                for f in (driver.trace, tracer.trace, render.render, knn.knn, tiles.render_tiles)}
    assert set(defaults.values()) == {DEFAULT_BACKEND}, defaults
    for argv in (["render", "sphere"], ["knn"]):
        assert build_parser().parse_args(argv).backend == DEFAULT_BACKEND
