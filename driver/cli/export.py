"""The request-stream export options of ``rayflex render`` (``driver.export``): checked with the
other outputs before any work, written inside the command's all-or-nothing commit."""

from __future__ import annotations

from pathlib import Path

DEFAULT_VCD_WINDOW = "0:100"


def add_export(p) -> None:
    from ..export import HEX_FILES, MAX_VCD_REQUESTS
    g = p.add_argument_group(
        "request-stream export",
        "the frame's datapath requests in issue order with the golden model's responses, to "
        "test another datapath on the same work (the frame is traced once more, on the golden "
        "model, tile by tile)")
    g.add_argument("--dump-requests", metavar="PATH.npz",
                   help="write the requests as an NPZ: requests (REQUEST_DTYPE), responses "
                        "(RESPONSE_DTYPE), ray, pixel, ray_type, format_version")
    g.add_argument("--dump-hex", metavar="DIR",
                   help=f"write {', '.join(HEX_FILES.values())} into the existing directory DIR "
                        "for $readmemh test benches: one request (response) per line, the packed "
                        "struct as one hex number, most significant digit first (format.txt "
                        "lists every field's bits)")
    g.add_argument("--vcd", metavar="PATH.vcd",
                   help="write the waveform of a window of the requests run through the RTL "
                        "(cycle by cycle, pyverilator), responses checked against the golden "
                        "model")
    g.add_argument("--vcd-window", metavar="FIRST:COUNT",
                   help=f"the requests of --vcd: COUNT (1..{MAX_VCD_REQUESTS:,}) from position "
                        f"FIRST of the stream (default {DEFAULT_VCD_WINDOW})")


class Export:
    """The export outputs asked for on the command line, checked and added to ``outs`` at
    construction (before any work); ``write`` traces the frame's stream into them (inside
    ``outs.commit()``). False when nothing was asked for."""

    def __init__(self, args, outs):
        from ..export import HEX_FILES, parse_window
        from ..core.outputs import HEX, NPZ, TEXT, VCD, OutputError
        self.outs, self.npz, self.hex, self.vcd, self.window = outs, None, None, None, None
        if args.vcd_window is not None and not args.vcd:
            raise ValueError("--vcd-window needs --vcd PATH")
        if args.vcd:
            self.window = parse_window(args.vcd_window or DEFAULT_VCD_WINDOW)
            import importlib.util
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
        from ..export import HexSink, NpzSink, WindowSink, export, write_vcd
        from ..core.progress import bar as progress_bar
        from ..tiles import DEFAULT_TILE, plan
        t = self.outs.temp
        sinks = []
        if self.npz:
            sinks.append(NpzSink(t(self.npz)))
        if self.hex:
            sinks.append(HexSink(t(self.hex["requests"]), t(self.hex["responses"]),
                                 t(self.hex["format"])))
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
