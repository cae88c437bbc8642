"""Design points: one definition of every option, the same in every command, and every option
reaching the part of the driver it sets."""

from __future__ import annotations

import argparse
import json

import pytest

from driver import design, rtunit
from driver.core.configs import ALL_CONFIGS, CONFIGS, DESIGN_CONFIGS, FUSED_SUFFIX, Q8_SUFFIX
from driver.cli import build_parser, main, options
from driver.design import OPTIONS, DesignPoint
from driver.cli.power import config_help

COMMANDS = ("render", "bench", "power", "sweep")


def _subparser(name):
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_takes_every_option_with_one_default(command):
    """Each command's parser has every design-point flag, with the definition's help and
    default (the help text is the one of ``OPTIONS``)."""
    p = _subparser(command)
    flags = {f: a for a in p._actions for f in a.option_strings}
    help_text = p.format_help()
    for o in OPTIONS:
        assert o.flag in flags, (command, o.flag)
        assert flags[o.flag].dest == o.name
        own = config_help() if (command, o.name) == ("power", "config") else o.help
        assert flags[o.flag].help.startswith(own), (command, o.flag)
        shown = "all" if (command, o.name) == ("power", "config") else o.describe_default()
        assert f"default: {shown}" in flags[o.flag].help         # power measures every one
    assert "docs/datapath.md" in help_text and "docs/workloads.md" in help_text


def test_defaults_are_the_rt_unit_and_memory_models_own():
    p = DesignPoint()
    assert p.memory() == rtunit.MemoryModel()
    assert p.rays_in_flight == rtunit.DEFAULT_RAYS_IN_FLIGHT
    assert DesignPoint(cache_kib=0).memory().cache_bytes == 0
    assert design.BY_NAME["config"].choices == tuple(DESIGN_CONFIGS)
    for name, (e, d) in CONFIGS.items():
        for c, x in ((0, 0), (1, 0), (0, 1), (1, 1)):
            q = DesignPoint(config=name + Q8_SUFFIX * c, latency=13,
                            transform="datapath" if x else "driver")
            assert q.backend_options() == {"extended": bool(e), "disjoint": bool(d),
                                           "latency": 13, "compressed": bool(c),
                                           "transform": bool(x)}
            assert q.rtl_params() == {"EXTENDED": e, "DISJOINT": d, "COMPRESSED": c,
                                      "TRANSFORM": x, "LATENCY": 13}
        # the latency defaults to the paper's: the q8 decode adds a stage; one less puts S9
        # beside the output format
        assert DesignPoint(config=name).latency == 11
        assert DesignPoint(config=name + Q8_SUFFIX).latency == 12
        assert DesignPoint(config=name + Q8_SUFFIX, latency=11).latency == 11
        with pytest.raises(ValueError, match="at least 11"):
            DesignPoint(config=name + Q8_SUFFIX, latency=10)
        # -fused: build parameter FUSED, passed only when set
        f = DesignPoint(config=name + Q8_SUFFIX + FUSED_SUFFIX)
        assert f.backend_options()["fused"] and f.rtl_params()["FUSED"] == 1 and f.latency == 12


def test_from_args_and_grid():
    p = _subparser("sweep")
    args = p.parse_args(["--config", "all", "--rays-in-flight", "16,64", "--cache-kib", "0,16",
                         "--scene", "sphere", "--size", "8"])
    grid = options.grid_from_args(args)
    assert len(grid) == len(DESIGN_CONFIGS) * 2 * 2
    assert {g.config for g in grid} == set(DESIGN_CONFIGS)
    assert {(g.rays_in_flight, g.cache_kib) for g in grid} == {(16, 0), (16, 16), (64, 0),
                                                             (64, 16)}
    assert all(g.scene == "sphere" and g.size == 8 for g in grid)
    # the -q8 configurations have their own least latency (12), so it varies with them
    assert design.varied(grid) == ["config", "latency", "rays_in_flight", "cache_kib"]
    assert len({g.key() for g in grid}) == len(grid)
    args = _subparser("render").parse_args(["sphere", "--cull-stack", "--latency", "12"])
    pt = options.from_args(args)
    assert pt.scene == "sphere" and pt.cull_stack is True and pt.latency == 12
    assert options.given(args) == ["--latency", "--cull-stack"]


@pytest.mark.parametrize("argv", [
    ["render", "sphere", "--config", "fast"],
    ["render", "sphere", "--latency", "5"],
    ["render", "sphere", "--cache-kib", "1", "--cache-ways", "32", "--rtunit"],
    ["render", "sphere", "--line-bytes", "48", "--rtunit"],
    ["render", "sphere", "--pipelines", "4"],                 # the RT unit needs --rtunit
    ["render", "sphere", "--scene", "room"],                  # the scene twice
    ["render", "sphere", "--mem-bytes-per-cycle", "0", "--rtunit"],
    ["bench", "--pipelines", "65"],
    ["bench", "--workload", "ao", "--spp", "0"],
    ["bench", "--bvh", "--config", "extended-unified"],
    ["sweep", "--config", "baseline-unified,nope"],
    ["sweep", "--rays-in-flight", "16,x"],
    ["sweep", "--cull-stack", "maybe"],
    ["power", "--latency", "100"],
    ["bench", "--warp-size", "3"],
    ["bench", "--warp-size", "32", "--rays-in-flight", "48"],
    ["bench", "--rt-preset", "rtx3090"],
    ["bench", "--frame", "megakernel"],
    ["bench", "--sector-bytes", "128"],                       # larger than a 64-byte line
    ["bench", "--l2-kib", "1", "--l2-ways", "64"],
    ["bench", "--rt-units", "0"],
    ["bench", "--workload", "path", "--ray-order", "hash"],   # sorting needs --frame wavefront
    ["sweep", "--rt-preset", "default,nope"],
    ["render", "sphere", "--rtunit", "--warp-size", "2", "--rays-in-flight", "3"],
    ["render", "sphere", "--ideal-replay"],                   # a second replay needs --rtunit
])
def test_bad_design_options_fail_in_one_line(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv + ["--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error: "), err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("tile", [[], ["--tile", "8"], ["--tile", "8", "--workers", "2"]],
                         ids=["whole", "tiled", "workers"])
def test_datapath_reaches_the_backend(tmp_path, tile):
    """--config and --latency build the backend of every render path: the golden model counts
    the latency it was given, and the RT-unit replay runs on the configuration's RTL."""
    out = tmp_path / "s.json"
    assert main(["render", "sphere", "--size", "12", "--backend", "golden", "--latency", "14",
                 "--config", "baseline-disjoint", "--no-progress", "--json", str(out),
                 "--out", str(tmp_path / "i.png"), *tile]) == 0
    doc = json.loads(out.read_text())
    assert doc["latency_cycles"] == 14
    assert all(t["latency_cycles"] == 14 for t in doc["by_type"].values())
    assert doc["provenance"]["design_point"]["config"] == "baseline-disjoint"


def test_render_rtunit_on_the_configuration(monkeypatch):
    """The whole frame's replay runs on the point's configuration (its RTL build parameters)."""
    from driver import stats
    from driver.backends import harness
    from driver.render import render
    seen = []
    real = harness.replay_schedule
    monkeypatch.setattr(harness, "replay_schedule", lambda params, *a, **k: seen.append(params)
                        or real(params, *a, **k))
    pt = DesignPoint(config="baseline-disjoint", size=8, rays_in_flight=4, cache_kib=16)
    res = render("sphere", 8, 8, backend="rtl", progress=False, point=pt, rtunit="ideal")
    assert len(seen) == 2 and all(p == {"EXTENDED": 0, "DISJOINT": 1, "COMPRESSED": 0,
                                        "TRANSFORM": 0, "LATENCY": 11} for p in seen)
    # traced on baseline-disjoint, so the replay is its timing; on another configuration
    # the replay evaluates that configuration's model
    assert res.stats["rtunit"]["rays_in_flight"] == 4
    assert res.stats["rtunit"]["replay_datapath"] == "timing"
    assert res.stats["rtunit_memory"]["cycles"] > res.stats["rtunit"]["cycles"]
    assert stats.WAVEFRONT in res.stats and res.stats["by_type"]["primary"]["rtunit"]


def test_presets_and_overrides():
    """--rt-preset sets a whole RT-unit configuration; options given with it override its
    values; the preset is in the design point (the JSON provenance)."""
    from driver.rtunit.presets import PRESETS
    p = options.from_args(_parse(["bench", "--rt-preset", "rtx2060-vulkan-sim"]))
    assert p.rt_preset == "rtx2060-vulkan-sim"
    for name, value in PRESETS["rtx2060-vulkan-sim"].values.items():
        assert getattr(p, name) == value, name
    q = options.from_args(_parse(["bench", "--rt-preset", "rtx2060-vulkan-sim", "--rt-units",
                                 "2", "--l2-kib", "0"]))
    assert (q.rt_units, q.l2_kib, q.cache_kib) == (2, 0, 64)
    d = options.from_args(_parse(["bench"]))
    assert d.rt_preset == "default" and d == DesignPoint()
    for name, value in PRESETS["default"].values.items():
        assert getattr(DesignPoint(), name) == value, name          # the defaults are the preset
    assert DesignPoint.preset("rtx2060-vulkan-sim", rt_units=4).rt_units == 4
    assert p.as_dict()["rt_preset"] == "rtx2060-vulkan-sim"
    # sweep: a list of presets, each point its preset's values unless an option is given
    pts = options.grid_from_args(_parse(["sweep", "--rt-preset", "default,rtx2060-vulkan-sim",
                                        "--mshrs", "8"]))
    assert [(x.rt_preset, x.rt_units, x.mshrs) for x in pts] == [
        ("default", 1, 8), ("rtx2060-vulkan-sim", 30, 8)]


def _parse(argv):
    from driver.cli import build_parser
    return build_parser().parse_args(argv)


def test_the_clock_given_timed_or_default(monkeypatch):
    """--clock-mhz, else the configuration's Fmax from the timing cache, else 1 GHz; the frame in
    real units at that clock."""
    design._cached_fmax.cache_clear()
    monkeypatch.setattr(design.timing, "cached_fmax", lambda c: None)
    p = DesignPoint()
    assert p.clock() == (1000.0, "default")
    assert DesignPoint(clock_mhz=250.0).clock() == (250.0, "--clock-mhz")
    design._cached_fmax.cache_clear()
    monkeypatch.setattr(design.timing, "cached_fmax",
                        lambda c: 42.5 if c == "baseline-unified" else None)
    assert DesignPoint().clock() == (42.5, "timing")
    assert DesignPoint(config="extended-unified").clock() == (1000.0, "default")
    stats = {"rays": 100, "wavefront": {"cycles": 850}, "rtunit": {"cycles": 1700}}
    c = design.clock_figures(DesignPoint(clock_mhz=500.0, rt_units=2), stats)
    assert c == {"clock_mhz": 500.0, "clock_source": "--clock-mhz", "frame_us": 3.4,
                 "rays_per_s_per_rt_unit": round(100 / 3.4e-6 / 2)}
    with pytest.raises(ValueError, match="--clock-mhz must be a clock in MHz"):
        DesignPoint(clock_mhz=0.0)
    design._cached_fmax.cache_clear()
