"""The documentation as a reference that cannot drift.

- docs/datapath.md's field tables equal the one layout table (``driver.core.layout``): a width or a
  bit position is defined once;
- README and docs speak about the product: no development words, no "SPEC n";
- every ``docs/...`` link and ``#section`` reference in README, docs and the driver's and tests'
  docstrings names a file and a heading that exist;
- every command's ``--help`` follows the same rules: product words only, references that resolve;
- every number the README quotes equals the JSON file it comes from (``tools/figures.py``'s
  ``README_NUMBERS``), and every figure shown is rebuilt by ``tools/figures.py``.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import re
import sys
from pathlib import Path

import pytest

from driver.core import layout, wire

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
COMMANDS = ("render", "bench", "power", "knn", "sweep", "study", "area", "timing")  # --help


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


def _slug(heading: str) -> str:
    """GitHub's anchor of a markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return {_slug(m.group(1)) for m in re.finditer(r"^#{1,6} (.+)$", text, flags=re.M)}


def _table(text: str, heading: str) -> list[list[str]]:
    """The rows (cells) of the first table after ``heading``."""
    after = text.split(heading, 1)[1]
    rows = []
    for line in after.splitlines()[1:]:
        s = line.strip()
        if not s.startswith("|"):
            if rows:
                break
            continue
        cells = [c.strip() for c in s.strip("|").split("|")]
        if set(cells[0]) <= set("-: "):
            continue
        rows.append(cells)
    return rows[1:]                                     # without the header


# ------------------------------------------------------------------------------------------------
# docs/datapath.md against driver.core.layout


@pytest.mark.parametrize("wire,heading", [(wire.REQUEST, "### Request fields"),
                                          (wire.RESPONSE, "### Response fields")])
def test_datapath_field_tables_equal_the_layout(wire, heading):
    rows = _table((DOCS / "datapath.md").read_text(), heading)
    doc = {}
    for name, word, bit, bits, elements, kind, _ in rows:
        shape = tuple(int(x) for x in elements.split("×"))
        doc[name.strip("`")] = (int(word), int(bit), int(bits), shape if shape != (1,) else (),
                                kind)
    want = {f.name: (f.word, f.lsb, f.bits, f.shape, "float32" if f.kind == "f32" else "uint")
            for f in wire.fields}
    assert doc == want


def test_datapath_words_and_node_tables_equal_the_layout():
    text = (DOCS / "datapath.md").read_text()
    assert f"A request is {wire.REQ_WORDS} little-endian 32-bit words and a response " \
           f"{wire.RSP_WORDS}" in " ".join(text.split())
    assert f"The first {wire.RAY_WORDS} words" in text
    for node, heading in ((layout.BOX_NODE, "**Box node**"),
                          (layout.TRI_NODE, "**Triangle node**")):
        rows = _table(text, heading)
        doc = [(r[0].strip("`"), int(r[1]), int(r[2])) for r in rows]
        assert doc == [(n, node.fields[n][1], node.fields[n][0].itemsize) for n in node.names]
        assert f"{heading}, {node.itemsize} bytes" in text
    for name, code in wire.OPCODES.items():
        assert f"`{name}` = {code}" in text


# ------------------------------------------------------------------------------------------------
# words and references


FORBIDDEN = [
    (re.compile(r"\bsessions?\b", re.I), "development history"),
    (re.compile(r"\bVMs?\b"), "the development machine"),
    # "issue" as the hardware's verb and noun (a ray may issue, an issue slot, issue order) is
    # product vocabulary; an issue of a tracker is not
    (re.compile(r"\bissues?\s*#?\d+|\b(?:the|this|that|an|known|open|fixed|github)\s+issues?\b"
                r"(?!\s+(?:slots?|order|width|queue)\b)", re.I), "issue numbers"),
    (re.compile(r"\btargets?\b", re.I), "development targets"),
    (re.compile(r"\bSPEC(?:'s)?\s*(?:sections?\s*)?\d", re.I), "an unshipped document"),
    (re.compile(r"\bnot met\b|\bmet in every\b", re.I), "development targets"),
]


def _forbidden(name: str, text: str) -> list[str]:
    return [f"{name}:{n}: {why}: {line.strip()[:100]}"
            for n, line in enumerate(text.splitlines(), 1)
            for pattern, why in FORBIDDEN if pattern.search(line)]


@pytest.mark.parametrize("page", _pages(), ids=lambda p: p.name)
def test_pages_speak_about_the_product(page):
    bad = _forbidden(page.name, page.read_text())
    assert not bad, "\n".join(bad)


def test_forbidden_words_keep_the_hardware_issue():
    assert not _forbidden("x", "a ray gives up its issue slot; requests in issue order")
    assert not _forbidden("x", "before the ray may issue; the issue slots; a ray issues again")
    assert _forbidden("x", "fixed in issue 12") and _forbidden("x", "the issue was the cache")
    assert _forbidden("x", "Issue #3: the cache") and _forbidden("x", "a known issue")
    assert _forbidden("x", "see SPEC 7") and _forbidden("x", "the speed target")


_MD_LINK = re.compile(r"\]\(([^)\s]+)\)")
_BARE_REF = re.compile(r"(?<![\w/(])(docs/[\w\-]+\.md)(#[\w\-]+(?:, #[\w\-]+)*)?")


def _references(path: Path):
    """(target file relative to ROOT, anchor or None) of every reference in ``path``."""
    text = path.read_text()
    if path.suffix == ".md":
        for m in _MD_LINK.finditer(text):
            target = m.group(1)
            if re.match(r"^[a-z]+:", target):            # http:, https:, mailto:
                continue
            file, _, anchor = target.partition("#")
            rel = (path.parent / file).resolve() if file else path.resolve()
            yield rel.relative_to(ROOT).as_posix(), anchor or None
    for m in _BARE_REF.finditer(text):
        anchors = re.findall(r"#([\w\-]+)", m.group(2) or "")
        for a in anchors or [None]:
            yield m.group(1), a


def _reference_sources() -> list[Path]:
    code = [p for p in (ROOT / "driver").rglob("*.py")] + list((ROOT / "tests").rglob("*.py"))
    return _pages() + sorted(code)


def _unresolved(target: str, anchor: str | None) -> str | None:
    """Why ``target#anchor`` does not resolve, or None."""
    path = ROOT / target
    if not path.exists():
        return f"{target} does not exist"
    if anchor and path.suffix == ".md" and anchor not in _anchors(path):
        return f"{target}#{anchor}: no such section"
    return None


def test_every_docs_reference_resolves():
    bad, seen = [], 0
    for src in _reference_sources():
        for target, anchor in _references(src):
            seen += 1
            why = _unresolved(target, anchor)
            if why:
                bad.append(f"{src.relative_to(ROOT)}: {why}")
    assert seen > 50
    assert not bad, "\n".join(bad)


def _help(command: str, capsys, monkeypatch) -> str:
    from driver.cli import main
    monkeypatch.setenv("COLUMNS", "400")               # no wrapping inside a reference
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("command", COMMANDS)
def test_help_speaks_about_the_product_and_its_references_resolve(command, capsys, monkeypatch):
    text = _help(command, capsys, monkeypatch)
    assert f"rayflex {command}" in text
    bad = _forbidden(f"rayflex {command} --help", text)
    refs = [(m.group(1), a) for m in _BARE_REF.finditer(text)
            for a in re.findall(r"#([\w\-]+)", m.group(2) or "") or [None]]
    bad += [f"rayflex {command} --help: {why}" for why in
            filter(None, (_unresolved(t, a) for t, a in refs))]
    assert refs or command == "knn", "a command's help names the docs page of its options"
    assert not bad, "\n".join(bad)


def test_unresolved_reference_is_reported():
    assert _unresolved("docs/datapath.md", None) is None
    assert _unresolved("docs/" + "no_such_page.md", None)      # (split: this file is scanned)
    assert _unresolved("docs/datapath.md", "no-such-section")


def test_slug_and_reference_parsing():
    assert _slug("Choices the paper leaves open") == "choices-the-paper-leaves-open"
    assert _slug("The node memory of the RT-unit model (`sim/rf_memory.h`)") == \
        "the-node-memory-of-the-rt-unit-model-simrf_memoryh"
    page = DOCS / "index.md"
    refs = set(_references(page))
    assert ("docs/datapath.md", None) in refs


# ------------------------------------------------------------------------------------------------
# the README's numbers and the figures


@functools.lru_cache(maxsize=None)
def _figures():
    """tools/figures.py (tools/ is not a package)."""
    spec = importlib.util.spec_from_file_location("rayflex_figures", ROOT / "tools" / "figures.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod                      # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


# Numbers in the README that are parameters of a command or a design, not measurements.
PARAMETERS = {"2", "3", "4", "5", "11", "16", "30", "32", "64", "128", "200", "256",  # sizes, ...
              "3.10",
              "2025", "2409.06000"}                                          # the paper


def _prose_numbers(text: str) -> list[str]:
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    text = re.sub(r"`[^`]*`", "", text)                       # commands, paths, options
    text = re.sub(r"\]\([^)]*\)", "]", text)                  # link targets
    return [n.rstrip(",") for n in
            re.findall(r"(?<![\w.])[+\u2212-]?\d[\d,]*(?:\.\d+)?(?: %)?", text)]


def test_readme_is_short_and_keeps_its_two_commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 150
    assert sum(ln.startswith(("# 1. ", "# 2. ")) for ln in lines) == 2


def test_readme_numbers_equal_their_json():
    readme = (ROOT / "README.md").read_text()
    numbers = _figures().readme_numbers()
    missing = {k: v for k, v in numbers.items() if v not in readme}
    assert not missing, f"README does not quote these as their JSON says: {missing}"
    quoted = set(numbers.values())
    stray = [n for n in _prose_numbers(readme) if n not in quoted and n not in PARAMETERS]
    assert not stray, f"README numbers that come from no JSON (add them to README_NUMBERS): {stray}"


def test_the_timing_page_quotes_its_json():
    """docs/timing.md's generated sections (the command and RTL, the tables, the text that quotes
    them, the flow's times, power at Fmax) are what tools/figures.py makes from docs/timing.json
    as it is; and each configuration timed there has its row."""
    page = (ROOT / "docs" / "timing.md").read_text()
    assert _figures().timing_page() == page, "run python tools/figures.py --timing-page"
    timed = json.loads((ROOT / "docs" / "timing.json").read_text())["configs"]
    for name, r in timed.items():
        assert f"| {name} | {r['fmax_mhz']:.1f} | {r['min_period_ns']:.2f} |" in page


def test_readme_number_check_catches_drift(tmp_path):
    figures = _figures()
    numbers = figures.readme_numbers()
    assert _prose_numbers("a 1,234 b `9,999` c [x](images/5.png) +3.1 % d") == ["1,234", "+3.1 %"]
    changed = tmp_path / "images"
    changed.mkdir()
    (tmp_path / "docs").mkdir()
    for file in {f for f, _, _ in figures.README_NUMBERS.values()}:
        (tmp_path / file).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / file).write_text((ROOT / file).read_text())
    stats = json.loads((tmp_path / "images/bunny_stats.json").read_text())
    stats["hits"] += 1
    (tmp_path / "images/bunny_stats.json").write_text(json.dumps(stats))
    assert figures.readme_numbers(tmp_path)["bunny_hits"] != numbers["bunny_hits"]


def test_every_figure_shown_is_rebuilt_by_tools_figures():
    figures = _figures()
    outputs = {o for f in figures.FIGURES for o in f.outputs}
    assert all((ROOT / o).is_file() for o in outputs), sorted(o for o in outputs
                                                              if not (ROOT / o).is_file())
    shown = set()
    for page in _pages():
        for m in re.finditer(r"((?:images|docs)/[\w\-]+\.(?:png|json))|\(([\w\-]+\.(?:png|json))\)",
                             page.read_text()):
            name = m.group(1) or f"{page.parent.relative_to(ROOT).as_posix()}/{m.group(2)}"
            shown.add(name.lstrip("./"))
    shown.discard("docs/figures.json")
    # a name with an upper-case placeholder ("images/compressed_path64_F.json for F = box32,
    # q8, q8g") stands for its expansions: at least one figure output must match it
    templates = {n for n in shown if re.search(r"[A-Z]", n)}
    for name in templates:
        pattern = re.sub(r"[A-Z]+", r"[a-z0-9]+", re.escape(name))
        assert any(re.fullmatch(pattern, o) for o in outputs), name
    shown -= templates
    assert shown and shown <= outputs, sorted(shown - outputs)
    manifest = json.loads((ROOT / "docs" / "figures.json").read_text())
    assert set(manifest) == set(figures.BY_NAME)
    for name, entry in manifest.items():
        assert entry["command"] == figures.BY_NAME[name].shown() and entry["commit"]
        assert entry["machine"]["cpu"] and entry["machine"]["cores"]


def test_figures_command_lists_and_rejects_unknown_names(capsys):
    figures = _figures()
    assert figures.main(["--list"]) == 0
    out = capsys.readouterr().out
    assert all(f.name in out for f in figures.FIGURES)
    with pytest.raises(SystemExit):
        figures.main(["--only", "no_such_figure"])


def test_the_tradeoffs_page_quotes_the_timing_of_its_builds():
    """docs/tradeoffs.md's Fmax and area of the shared-register build are those of
    docs/timing_tradeoffs.json (the ``timing_tradeoffs`` figure)."""
    page = (ROOT / "docs" / "tradeoffs.md").read_text()
    cfgs = json.loads((ROOT / "docs" / "timing_tradeoffs.json").read_text())["configs"]
    base, shared = cfgs["extended-unified"], cfgs["extended-unified-shared"]
    for r in (base, shared):
        assert f"{r['fmax_mhz']:.1f} MHz" in page or f"against {r['fmax_mhz']:.1f}" in page
        assert f"{r['area_um2'] / 1e6:.2f}" in page and f"{r['flip_flops']:,}" in page
    assert f"({(shared['fmax_mhz'] / base['fmax_mhz'] - 1) * 100:.1f} %)".replace("-", "−") in page


def test_the_rt_unit_page_quotes_its_full_size_runs():
    """docs/rtunit_rtl.md's table of the full-size frames is tools/replay_vs_unit.py's table of
    docs/rtunit_replay_full.json, and that JSON holds what the page says of it: every ray equal
    to the traversal, none wrong by Embree's adjudication, the replay within 0.5 %."""
    spec = importlib.util.spec_from_file_location("replay_vs_unit",
                                                  ROOT / "tools" / "replay_vs_unit.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    rows = json.loads((ROOT / "docs" / "rtunit_replay_full.json").read_text())["runs"]
    assert [r["run"] for r in rows] == tool.FULL
    assert tool.table(rows) in (ROOT / "docs" / "rtunit_rtl.md").read_text()
    for r in rows:
        assert r["mismatches"] == 0 and r["embree_datapath_wrong"] == 0
        assert abs(r["ratio"] - 1) < 0.005


def test_the_rt_unit_page_quotes_its_lumibench_runs_with_instances():
    """docs/rtunit_rtl.md's table of LumiBench's runs with their instances is
    tools/unit_lumibench.py's table of docs/rtunit_lumibench.json, and the JSON holds what the
    page says of them: every ray equal to the traversal at both depths, none wrong by Embree,
    no overflow at depth 32, the same ops at depth 8, the replay within 0.06 %."""
    spec = importlib.util.spec_from_file_location("unit_lumibench",
                                                  ROOT / "tools" / "unit_lumibench.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    doc = json.loads((ROOT / "docs" / "rtunit_lumibench.json").read_text())
    page = (ROOT / "docs" / "rtunit_rtl.md").read_text()
    assert tool.table(doc) in page and len(doc["depth_32"]) == 12
    for name, a in doc["depth_32"].items():
        b = doc["depth_8"][name]
        assert a["traversal_mismatches"] == b["traversal_mismatches"] == 0
        assert a["datapath_wrong"] == b["datapath_wrong"] == 0
        assert a["stack_overflows"] == 0 and b["max_stack_depth"] == 8
        assert [a[k] for k in ("box_ops", "tri_ops", "transform_ops")] == \
            [b[k] for k in ("box_ops", "tri_ops", "transform_ops")]
        for r in (a, b):                                  # "within 0.06 %"
            assert round(abs(r["replay_cycles_ratio"] - 1) * 100, 2) <= 0.06
    flat = " ".join(page.split())
    for depth in ("depth_32", "depth_8"):
        s = doc["suites"][depth]
        assert f"takes {s['wall_s']:.1f} s" in flat or f"and {s['wall_s']:.1f} s" in flat
        assert f"commit {s['commit'][:7]}" in flat


def test_the_tradeoffs_page_quotes_the_timing_of_the_fused_build():
    """docs/tradeoffs.md's Fmax and area of the fused build are docs/timing_fused.json's (the
    ``timing_fused`` figure: both builds mapped by ABC's fast script)."""
    page = (ROOT / "docs" / "tradeoffs.md").read_text()
    doc = json.loads((ROOT / "docs" / "timing_fused.json").read_text())
    base, fused = doc["configs"]["baseline-unified"], doc["configs"]["baseline-unified-fused"]
    assert base["abc_script"] == fused["abc_script"] == "fast"
    flat = " ".join(page.split())
    assert f"reaches {fused['fmax_mhz']:.1f} MHz against the baseline's {base['fmax_mhz']:.1f}" \
        in flat
    assert f"({(fused['fmax_mhz'] / base['fmax_mhz'] - 1) * 100:.1f} %)".replace("-", "−") in flat
    assert (f"{fused['area_um2'] / 1e6:.2f} against {base['area_um2'] / 1e6:.2f} mm²" in flat
            and f"{fused['flip_flops']:,} against {base['flip_flops']:,}" in flat)
    assert f"{fused['stages']['S1']['min_period_ns']:.2f} ns" in flat
