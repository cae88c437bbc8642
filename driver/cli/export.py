"""The request-stream export options of ``rayflex render`` (``driver.export``): checked with the
other outputs before any work, written inside the command's all-or-nothing commit."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from ..core.outputs import HEX, NPZ, TEXT, VCD, OutputError
from ..core.progress import bar as progress_bar
from ..export import HEX_FILES, HexSink, NpzSink, WindowSink, export, parse_window, write_vcd
from ..tiles import DEFAULT_TILE, plan

DEFAULT_VCD_WINDOW = "0:100"


class Export:
    """The export outputs asked for on the command line, checked and added to ``outs`` at
    construction (before any work); ``write`` traces the frame's stream into them (inside
    ``outs.commit()``). False when nothing was asked for."""

    def __init__(self, args, outs):
        self.outs, self.npz, self.hex, self.vcd, self.window = outs, None, None, None, None
        if args.vcd_window is not None and not args.vcd:
            raise ValueError("--vcd-window needs --vcd PATH")
        if args.vcd:
            self.window = parse_window(args.vcd_window or DEFAULT_VCD_WINDOW)
            if importlib.util.find_spec("pyverilator") is None:
                raise ValueError("--vcd needs the pyverilator backend (pip install "
                                 "pyverilator-mm)")
            self.vcd = outs.add("--vcd", args.vcd, VCD)
        if args.dump_requests:
            self.npz = outs.add("--dump-requests", args.dump_requests, NPZ)
        if args.dump_hex:
            d = Path(args.dump_hex).expanduser()
            if not d.is_dir():
                raise OutputError(f"--dump-hex {args.dump_hex}: not an existing directory")
            kinds = {"requests": HEX, "responses": HEX, "format": TEXT}
            self.hex = {k: outs.add(f"--dump-hex {k}", d / name, kinds[k])
                        for k, name in HEX_FILES.items()}

    def __bool__(self) -> bool:
        return bool(self.npz or self.hex or self.vcd)

    def write(self, scene, width: int, height: int, workload: str, options: dict, tile,
              tree: dict, progress: bool, backend_options: dict | None = None) -> int:
        """Trace the frame's request stream into the outputs' temporary files; returns the
        number of requests."""
        t = self.outs.temp
        sinks = []
        if self.npz:
            sinks.append(NpzSink(t(self.npz)))
        if self.hex:
            npz = self.npz and os.path.relpath(self.npz, self.hex["format"].parent)
            sinks.append(HexSink(t(self.hex["requests"]), t(self.hex["responses"]),
                                 t(self.hex["format"]), npz))
        win = WindowSink(*self.window) if self.vcd else None
        if win:
            sinks.append(win)
        tiles = len(plan(width, height, tile or DEFAULT_TILE))
        bar = progress_bar(tiles, f"{scene.name} request stream (golden)", "tile", progress)
        try:
            n = export(scene, width, height, sinks, workload, options, tile, tree["fill"],
                       tree["cull_stack"], bar.hook, tree.get("bvh_format", "box32"))
        finally:
            bar.close()
        if win:
            write_vcd(t(self.vcd), *win.window(), backend_options)
        return n
