"""Each command of the README's question table prints what the table says it prints.

The commands are read from README.md itself and run at a small size (``--size 8``, four kNN
queries); for each question, each phrase of its "what it prints" cell that ``EXPECT`` lists must
still be in the README and its pattern must match the command's standard output (as many times
as a third number says). The power and
area questions build or synthesize every configuration (minutes): ``-m slow``.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from driver.cli import main
from support.prebuild import SUITE_RAYS
from test_lumibench_scenes import suite_root

ROOT = Path(__file__).resolve().parent.parent
SMALL = "8"

# bench --workload's row of a ray type: rays, box/ray, tri/ray, xf/ray, util ("-" in a one-kernel
# frame), latency, p95, and the bytes per ray from L1, L2 and DRAM
TYPE_ROW = (r"^\s*{t}\s+\d+\s+[\d.]+\s+[\d.]+\s+[\d.]+\s+(?:[\d.]+|-)\s+\d+\s+\d+\s+\d+\s+\d+"
            r"\s+\d+")
EXPECT = {
    "Does my RTL change still trace correctly?": [
        ("rays", r"\b\d+ rays\b"), ("hits", r"\b\d+ hits\b"),
        ("box and triangle ops per ray", r"[\d.]+ box \+ [\d.]+ tri ops per ray"),
        ("cycles", r"\b\d+ cycles\b"),
        ("every ray classified against Embree",
         r"embree: \d+ rays compared, \d+ hit/miss mismatches, \d+ primitive mismatches")],
    "How does my design do on the field's benchmark?": [
        ("LumiBench's scenes (`lumibench:ID`) × its path-tracing, shadow and AO shaders",
         r"^(BATH|SHIP)_(PT|SH|AO)\s+\d", 6),
        ("every ray checked", r"agree\s+edge_tie\s+embree_wrong\s+datapath_wrong"),
        ("ops, utilization with the node memory, bytes, hit rate and energy per ray",
         r"ops/ray\s+util_mem\s+B/ray\s+hit_rate\s+energy/ray"),
        ("a table and a figure", r"wrote .*summary\.csv, .*summary\.png")],
    "Is the memory side the bottleneck, on one RT unit or a GPU's thirty?": [
        ("warps of 32 threads to 30 RT units", r"RT units 30 x R=128 P=1 warp 32, one-kernel"),
        ("its cycles and utilization with the memory hierarchy (`rtunit_memory`)",
         r"\d+ cycles, utilization [\d.]+, .*\(memory hierarchy"),
        ("with free node fetches (`rtunit`)",
         r"\d+ cycles, utilization [\d.]+, .*\(node fetches free"),
        ("SIMT efficiency", r"SIMT efficiency [\d.]+"),
        ("rays held per unit over time", r"[\d.]+ rays held per RT unit"),
        ("each level's hits, merged misses, bytes and waits",
         r"L1 [\d,]+ accesses, [\d,]+ hits \([\d,]+ merged misses\), [\d,]+ bytes filled, "
         r"[\d,]+ cycles waited; L2 [\d,]+ accesses"),
        ("MSHR stalls", r"[\d,]+ MSHR stalls"),
        ("per ray type its latency and the bytes each memory level supplied",
         TYPE_ROW.format(t="ao")),
        ("every ray checked against Embree", r"embree: \d+ rays compared")],
    "Where is the design's sweet spot?": [
        ("every combination, per ray type and for the frame",  # 2 configs x 2 pools x 2 caches
         r"^\s*baseline-(unified|disjoint)\s+\d+\s+\d+\s+ao\s+\d+", 8),
        ("every combination, per ray type and for the frame",
         r"^\s*baseline-(unified|disjoint)\s+\d+\s+\d+\s+all\s+\d+", 8),
        ("ops, utilization with the memory hierarchy, latency",
         r"ops/ray\s+util\s+ideal\s+latency"),
        ("bytes from DRAM, datapath energy and node-fetch energy per ray",
         r"B/ray\s+E/ray\s+mem pJ/ray")],
    "What does each ray type cost in energy?": [
        ("energy per box, triangle", r"\| configuration \| box \|.*\| triangle \|"),
        ("of each configuration", r"\| baseline-unified \| [\d,]+ \|"),
        ("per ray of every ray type", r"(?m)^\| (primary|shadow|bounce1) \| [\d.]+ \|")],
    "Do compressed nodes pay off?": [
        ("64-byte quantized nodes and triangle-pair leaves", r"BVH4 q8: "),
        ("bytes per triangle", r"BVH4 q8: [\d,]+ bytes, [\d.]+ bytes per triangle"),
        ("the frame's cycles and utilization", r"\d+ cycles, utilization [\d.]+"),
        ("bytes and latency per ray type", TYPE_ROW.format(t="shadow"))],
    "In which order should rays enter the RT unit?": [
        ("the replay under a ray-order policy", TYPE_ROW.format(t="ao")),
        ("rays held, state bytes",
         r"ray order: affinity, window 256; \d+ rays held \(\d+ beyond the pool\), [\d,]+ bytes "
         r"of traversal state")],
    "Can my own datapath RTL run the same work?": [
        ("NPZ", r"wrote .*req\.npz"),
        ("`$readmemh` hex files with their bit layout",
         r"hex/requests\.hex, hex/responses\.hex, hex/format\.txt"),
        ("a waveform", r"wrote .*w\.vcd")],
    "Does the extended datapath pay off on kNN?": [
        ("beats, cycles, utilization", r"\d+ beats \(ops\) in \d+ cycles, utilization [\d.]+"),
        ("agreement with float64", r"agreement with exact float64 search: [\d.]+ %")],
    "Does the timing model hold against an RT unit in RTL?": [
        ("cycles, utilization and deepest stack",
         r"RT unit in RTL .*: \d+ cycles, utilization [\d.]+, max stack depth \d+"),
        ("every ray compared with the Python traversal", r"\b0 rays differ from the traversal"),
        ("the replay's cycles as a ratio of the unit's", r"replay cycles [\d.]+ x the unit's")],
    "Should the instance transform run on the datapath?": [
        ("TRANSFORM ops per ray beside box and triangle ops", r"box/ray\s+tri/ray\s+xf/ray"),
        ("per ray type", TYPE_ROW.format(t="primary")),
        ("the frame's cycles and utilization", r"RT units 1 x .*: \d+ cycles, utilization [\d.]+"),
        ("a ray type's own cycles and utilization with `--frame wavefront`",
         r"one-kernel frame: its ray types share the pipelines.*--frame wavefront gives each")],
    "How big is each configuration?": [
        ("Yosys cell counts", r"cells"),
        ("of the four configurations", r"extended-disjoint"),
        ("against the paper's area", r"paper")],
    "What clock does each configuration reach, and which stage sets it?": [
        ("Fmax, the stage that sets it and the cells on its path",
         r"\| Fmax \(MHz\) \| least period \(ns\) \| limiting stage \| cells on its path \|"),
        ("each pipeline stage's least clock period", r"^\| baseline-unified \| [\d.*| ]+\|$"),
        ("the q8 decode and TRANSFORM", r"baseline-unified-(q8|xf) \| [\d.]+ \|", 2)],
}
SLOW = {"What does each ray type cost in energy?", "How big is each configuration?",
        "What clock does each configuration reach, and which stage sets it?"}


def questions() -> dict[str, tuple[str, str]]:
    """{question: (command, what it prints)} from the README's question table."""
    text = (ROOT / "README.md").read_text()
    section = text.split("## Questions you can answer", 1)[1].split("\n## ", 1)[0]
    out = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if len(cells) == 3 and cells[1].startswith("`"):
            out[cells[0]] = (cells[1].strip("`"), cells[2])
    return out


def small(argv: list[str], lumibench_root: Path | None = None) -> list[str]:
    """The README command at a small size (a LumiBench root ``DIR``: ``lumibench_root``)."""
    argv = [str(lumibench_root) if a == "DIR" and lumibench_root else a for a in argv]
    if "--size" in argv:
        argv[argv.index("--size") + 1] = SMALL
    elif argv[:2] in (["rayflex", "render"], ["rayflex", "bench"], ["rayflex", "sweep"],
                      ["rayflex", "power"], ["rayflex", "suite"]):
        argv += ["--size", SMALL]
    if argv[:2] == ["rayflex", "knn"]:
        argv += ["--queries", "4"]
    if "rtunit" in argv and "--rays-in-flight" not in argv:
        argv += ["--rays-in-flight", str(SUITE_RAYS)]   # the RT unit the suite builds anyway
    if argv[0] == "rayflex":
        argv.append("--no-progress")
    return argv


def test_the_table_lists_every_question():
    assert set(questions()) == set(EXPECT)


@pytest.mark.parametrize("question", [
    pytest.param(q, marks=pytest.mark.slow) if q in SLOW else q for q in EXPECT])
def test_each_question_prints_what_the_readme_says(question, in_tmp, capsys, monkeypatch):
    command, prints = questions()[question]
    out = ""
    for part in command.split(" && "):
        argv = shlex.split(part)
        if argv[:2] == ["mkdir", "-p"]:
            for d in argv[2:]:
                (in_tmp / d).mkdir(parents=True, exist_ok=True)
        elif argv[0] == "rayflex" and "--vcd" in argv:
            # the waveform loads a pyverilator model, which cannot share a process with another
            # one (tests/test_export.py runs it apart too)
            run = subprocess.run([sys.executable, "-m", "driver.cli", *small(argv)[1:]],
                                 capture_output=True, text=True, cwd=in_tmp, timeout=3600,
                                 env={**os.environ, "PYTHONPATH": str(ROOT)})
            assert run.returncode == 0, run.stderr
            out += run.stdout
        elif argv[0] == "rayflex":
            root = None
            if "DIR" in argv:               # a LumiBench root: a tiny one, no scene cache
                root = suite_root(in_tmp / "lumi")
                monkeypatch.setenv("RAYFLEX_SCENE_CACHE", "0")
            assert main(small(argv, root)[1:]) == 0, capsys.readouterr().err
            out += capsys.readouterr().out
        elif argv[:2] == ["python", "-m"]:
            run = subprocess.run([sys.executable, *argv[1:]], capture_output=True, text=True,
                                 cwd=in_tmp, timeout=3600)
            assert run.returncode == 0, run.stderr
            out += run.stdout
        else:
            raise AssertionError(f"the test cannot run {part!r}: teach it")
    for phrase, pattern, *times in EXPECT[question]:
        assert phrase in prints, f"the README no longer says {phrase!r}: update EXPECT"
        found = len(re.findall(pattern, out, re.MULTILINE))
        assert found >= (times or [1])[0], \
            f"{question}: the output does not show {phrase!r} ({pattern!r}):\n{out}"
