"""Request-stream export (``driver.export``, ``rayflex render --dump-requests/--dump-hex/--vcd``):
the dumped requests run on golden and on the RTL give the dumped responses bit for bit, a hex line
decodes to its request, the stream is the frame's (same ops, ray types, rays), and bad export
arguments fail before any work with nothing written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import driver
from driver import export as ex
from driver.cli import main
from driver.design import DesignPoint
from driver.core.wire import (REQUEST, REQUEST_DTYPE, RESPONSE, RESPONSE_DTYPE, pack_requests,
                              pack_responses)
from driver.render import render
from driver.scenes.scene import load_scene


def dump(path, scene, w, h, workload="primary", **options):
    """Export ``scene`` (a name or a loaded scene) to ``path``; (requests, the file read back)."""
    sink = ex.NpzSink(path)
    scene = load_scene(scene) if isinstance(scene, str) else scene
    n = ex.export(scene, w, h, [sink], workload, options, tile=16)
    return n, ex.load(path)


@pytest.mark.parametrize("scene, workload", [("sphere", "primary"), ("cornell", "path"),
                                             ("bunny_grid", "ao")])
def test_dump_round_trip_golden_and_rtl(tmp_path, scene, workload):
    scene = load_scene(scene)                   # once: bunny_grid's instances take seconds
    n, d = dump(tmp_path / "d.npz", scene, 24, 20, workload)
    req, rsp = d["requests"], d["responses"]
    assert req.dtype == REQUEST_DTYPE and rsp.dtype == RESPONSE_DTYPE
    assert len(req) == len(rsp) == len(d["ray"]) == len(d["pixel"]) == len(d["ray_type"]) == n
    assert int(d["format_version"]) == ex.FORMAT_VERSION
    # the frame's stream: the same ops per ray type as the render of that frame
    frame = render(scene, 24, 20, backend="golden", progress=False,
                   point=DesignPoint(workload=workload), tile=16)
    by_type = frame.stats["by_type"] if "by_type" in frame.stats else {"primary": frame.stats}
    for kind, s in by_type.items():
        assert int((d["ray_type"] == kind).sum()) == s["ops"], kind
    assert set(np.unique(d["ray_type"])) == set(by_type)
    assert 0 <= d["pixel"].min() and d["pixel"].max() < 24 * 20
    # each request names its frame-wide ray (an instanced scene's too), and that ray's pixel
    rays = sum(s["rays"] for s in by_type.values())
    assert 0 <= d["ray"].min() and d["ray"].max() < rays
    first = np.unique(d["ray"], return_index=True)[1]
    pixel_of = dict(zip(d["ray"][first].tolist(), d["pixel"][first].tolist()))
    assert all(pixel_of[r] == p for r, p in zip(d["ray"].tolist(), d["pixel"].tolist()))
    # replayed: bit-exact on both models
    for name in ("golden", "rtl"):
        be = driver.backend(name)
        got = np.concatenate([be.run(req[i:i + 20000]) for i in range(0, n, 20000)])
        assert np.array_equal(pack_responses(got), pack_responses(rsp)), name


def test_hex_lines_decode_to_their_requests(tmp_path):
    scene = load_scene("sphere")
    sink = ex.NpzSink(tmp_path / "d.npz")
    hexs = ex.HexSink(tmp_path / "r.hex", tmp_path / "s.hex", tmp_path / "f.txt")
    n = ex.export(scene, 12, 10, [sink, hexs])
    d = ex.load(tmp_path / "d.npz")
    req_lines = (tmp_path / "r.hex").read_text().splitlines()
    rsp_lines = (tmp_path / "s.hex").read_text().splitlines()
    assert len(req_lines) == len(rsp_lines) == n > 0
    for i in (0, 1, n // 2, n - 1):
        assert np.array_equal(pack_requests(ex.decode_hex(req_lines[i])),
                              pack_requests(d["requests"][i:i + 1]))
        assert ex.decode_hex(rsp_lines[i], RESPONSE).tobytes() == d["responses"][i:i + 1].tobytes()
    # bit b of the number is bit b of the struct: the tag is the low 32 bits, the opcode the
    # low bits of word 1, as driver.core.layout places them
    line = int(req_lines[n - 1], 16)
    for name in ("tag", "opcode"):
        f = REQUEST.field[name]
        assert (line >> f.first_bit) & ((1 << f.bits) - 1) == int(d["requests"][name][n - 1])
    fmt = (tmp_path / "f.txt").read_text()
    for f in REQUEST.fields:
        assert f"[{f.first_bit + f.total_bits - 1}:{f.first_bit}]" in fmt


def test_window_sink_and_parse():
    assert ex.parse_window("5:10") == (5, 10)
    for bad in ("5", "a:1", "-1:3", "0:0", f"0:{ex.MAX_VCD_REQUESTS + 1}"):
        with pytest.raises(ValueError, match="FIRST:COUNT"):
            ex.parse_window(bad)
    req = np.zeros(10, REQUEST_DTYPE)
    req["tag"] = np.arange(10)
    rsp = np.zeros(10, RESPONSE_DTYPE)
    w = ex.WindowSink(3, 5)
    for lo in (0, 4, 7):
        hi = {0: 4, 4: 7, 7: 10}[lo]
        w.add(ex.Chunk("primary", req[lo:hi], rsp[lo:hi], np.arange(lo, hi), np.arange(lo, hi)))
    assert w.window()[0]["tag"].tolist() == [3, 4, 5, 6, 7] and w.done
    late = ex.WindowSink(8, 5)
    late.add(ex.Chunk("primary", req, rsp, np.arange(10), np.arange(10)))
    with pytest.raises(ValueError, match="ends after the frame's 10 requests"):
        late.window()


def test_a_vcd_window_alone_stops_the_stream_early():
    scene = load_scene("sphere")
    whole = ex.export(scene, 16, 16, [ex.WindowSink(0, 10**9)])
    win = ex.WindowSink(5, 20)
    early = ex.export(scene, 16, 16, [win], tile=4)
    assert 25 <= early < whole
    assert len(win.window()[0]) == 20


def test_cli_dump_and_vcd(tmp_path):
    """The CLI writes all three exports; the VCD (pyverilator, its own process: one model per
    process) holds the datapath's signals and the window's cycles."""
    (tmp_path / "hx").mkdir()
    cmd = [sys.executable, "-m", "driver.cli", "render", "sphere", "--size", "12", "--backend",
           "golden", "--no-progress", "--dump-requests", "d.npz", "--dump-hex", "hx",
           "--vcd", "w.vcd", "--vcd-window", "3:7"]
    root = str(Path(driver.__file__).resolve().parent.parent)       # this tree's driver
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [root, *filter(None, [os.environ.get("PYTHONPATH")])])}
    r = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    d = ex.load(tmp_path / "d.npz")
    assert len((tmp_path / "hx" / "requests.hex").read_text().splitlines()) == len(d["ray"])
    vcd = (tmp_path / "w.vcd").read_text()
    assert "$enddefinitions" in vcd and "req_i" in vcd and "rsp_o" in vcd
    # format.txt names the NPZ written with it as it is (it once said requests.npz), from hx/
    fmt = (tmp_path / "hx" / "format.txt").read_text()
    assert "../d.npz (--dump-requests) holds the ray and pixel of each." in fmt
    assert "requests.npz" not in fmt
    assert "in the NPZ of --dump-requests PATH.npz" in ex.hex_format()


@pytest.mark.parametrize("args, words", [
    (["--dump-requests", "d.txt"], "unknown extension"),
    (["--dump-requests", "no/dir/d.npz"], "does not exist"),
    (["--dump-requests", "/proc/d.npz"], "cannot write in /proc"),
    (["--dump-hex", "nodir"], "not an existing directory"),
    (["--dump-hex", "same.png"], "not an existing directory"),
    (["--vcd", "w.txt"], "unknown extension"),
    (["--vcd-window", "0:5"], "--vcd-window needs --vcd"),
    (["--vcd", "w.vcd", "--vcd-window", "x"], "FIRST:COUNT"),
    (["--vcd", "w.vcd", "--vcd-window", "0:0"], "FIRST:COUNT"),
    (["--dump-requests", "same.npz", "--vcd", "same.npz"], "extension"),
    (["--dump-requests", "x.npz", "--out", "x.npz"], "extension"),
])
def test_bad_export_arguments_fail_before_any_work(error_line, tmp_path, monkeypatch, args,
                                                   words):
    import driver.render
    monkeypatch.chdir(tmp_path)
    (tmp_path / "same.png").write_bytes(b"keep me")

    def no_render(*a, **k):
        raise AssertionError("rendered before checking the export arguments")
    monkeypatch.setattr(driver.render, "render", no_render)
    assert main(["render", "sphere", "--size", "8", "--backend", "golden", *args]) == 2
    assert words in error_line()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["same.png"]
