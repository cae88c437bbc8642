"""Output files of the command line: checked before any work, written atomically, all or nothing.

    outs = Outputs()
    img = outs.add("--out", "bunny.png", IMAGE)          # checks at once (see ``add``)
    js = outs.add("--json", "frame.json", JSON)
    ...long work...
    with outs.commit():                                  # nothing is visible until every file is
        save_image(image, outs.temp(img))                # written; on any error, no file is left
        write_json(doc, outs.temp(js))

``add`` refuses, with a one-line ``OutputError`` (a ``ValueError``), before any work: a path that
names a directory, a missing or unwritable directory (probed by creating a file in it, so a
read-only file system or ``/proc`` is caught as well as permissions), two outputs naming the same
file, an output naming an input, and an extension that does not match what is written (images:
any format Pillow can write, chosen by extension, so ``x.jpg`` is JPEG; JSON: ``.json``).

``commit`` writes each file to a temporary file beside its target (same directory, so the final
rename is atomic and never crosses file systems; same suffix, so writers that pick a format by
extension see the right one) and renames them all into place only once every file is written.
A failure (full disk, interrupt) removes every temporary file and leaves the targets untouched.
Once every file is complete and the renames begin, ``written()`` is true: from then on the
command line (``driver.cli.main``) lets a Ctrl-C or SIGTERM neither stop the renames half way
nor call the outputs lost; the command ends as finished.
This module exists because neither the standard library nor Pillow/matplotlib offer a
multi-file, all-or-nothing write; it is the small part that has to be hand-written.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import threading
from pathlib import Path

import numpy as np
from PIL import Image

from .errors import RayflexError


_WRITTEN = threading.Event()       # a commit of this process is renaming or has renamed its files


def written() -> bool:
    """True once a ``commit`` of this process has every file complete and is putting them in
    place (renames only) or has put them."""
    return _WRITTEN.is_set()


def forget_written() -> None:
    """Start a new command: ``written()`` is false until its outputs are in place."""
    _WRITTEN.clear()


class OutputError(RayflexError):
    """An output path that cannot be written (one-line message naming the flag and path)."""


def image_extensions() -> dict[str, str]:
    """Extension (lower case, with dot) -> Pillow format name, for every format Pillow can write
    an RGB image in (PNG, JPEG, TIFF, WebP, BMP, ...)."""
    Image.init()
    rgb_ok = {"PNG", "JPEG", "TIFF", "WEBP", "BMP", "PPM", "TGA", "QOI", "SGI", "PCX", "AVIF",
              "JPEG2000"}
    return {ext: fmt for ext, fmt in Image.registered_extensions().items()
            if fmt in Image.SAVE and fmt in rgb_ok}


IMAGE = "image"
JSON = "json"
TABLE = "table"           # kNN neighbours: .json or .csv
PNG = "png"               # plots matplotlib writes as PNG
NPZ, VCD, HEX, TEXT = "npz", "vcd", "hex", "text"       # request-stream export (driver.export)
_KIND_EXT = {JSON: (".json",), TABLE: (".json", ".csv"), PNG: (".png",), NPZ: (".npz",),
             VCD: (".vcd",), HEX: (".hex",), TEXT: (".txt",)}


def extensions(kind: str) -> tuple[str, ...]:
    """The extensions accepted for an output kind."""
    return tuple(sorted(image_extensions())) if kind == IMAGE else _KIND_EXT[kind]


class Outputs:
    """The output files of one command: checked when added, written all or nothing."""

    def __init__(self, inputs=()):
        self._targets: dict[str, Path] = {}        # flag -> resolved target
        self._temps: dict[Path, Path] = {}
        self._inputs = {_key(Path(p)): str(p) for p in inputs if p and Path(p).exists()}

    def add(self, flag: str, path, kind: str) -> Path:
        """Check one output path now (see module docstring); return it as a Path."""
        p = Path(path).expanduser()
        if p.is_dir():
            raise OutputError(f"{flag} {path} is a directory, not a file")
        ext = p.suffix.lower()
        allowed = extensions(kind)
        if ext not in allowed:
            shown = (" or ".join(allowed) if len(allowed) <= 2
                     else ".png, .jpg, .tif, .webp, ..." if kind == IMAGE else ", ".join(allowed))
            raise OutputError(f"{flag} {path}: unknown extension {p.suffix or '(none)'!r} for "
                              f"this output (use {shown})")
        parent = p.parent if str(p.parent) else Path(".")
        if not parent.is_dir():
            raise OutputError(f"{flag} {path}: output directory does not exist: {parent}")
        key = _key(p)
        for other, q in self._targets.items():
            if _key(q) == key:
                raise OutputError(f"{flag} {path} names the same file as {other} "
                                  "(each output needs its own file)")
        if key in self._inputs:
            raise OutputError(f"{flag} {path} would overwrite the input {self._inputs[key]}")
        if p.exists() and not os.access(p, os.W_OK):
            raise OutputError(f"{flag} {path}: file is not writable")
        _probe_writable(parent, flag, path)
        self._targets[flag] = p
        return p

    def paths(self) -> list[Path]:
        return list(self._targets.values())

    def temp(self, target: Path) -> Path:
        """Inside ``commit``: the temporary file to write instead of ``target``."""
        return self._temps[target]

    @contextlib.contextmanager
    def commit(self):
        """Create a temporary file per target; after the block, rename them all into place.
        On any exception, remove every temporary file and re-raise."""
        try:
            for p in self._targets.values():
                fd, name = tempfile.mkstemp(prefix=f".{p.stem}.", suffix=p.suffix,
                                            dir=p.parent if str(p.parent) else ".")
                os.close(fd)
                self._temps[p] = Path(name)
            yield self
            if self._temps:
                _WRITTEN.set()                       # the renames: a signal waits for them
            for p, tmp in self._temps.items():
                if p.exists():                       # keep an existing file's permissions
                    os.chmod(tmp, p.stat().st_mode & 0o7777)
                else:
                    os.chmod(tmp, 0o666 & ~_umask())
                os.replace(tmp, p)
        finally:
            for tmp in self._temps.values():
                with contextlib.suppress(OSError):
                    tmp.unlink()
            self._temps.clear()


def _key(p: Path) -> str:
    """One spelling per file: resolved path (links followed), case as on disk."""
    try:
        return str(p.expanduser().resolve())
    except OSError:
        return os.path.abspath(p)


def _probe_writable(parent: Path, flag: str, path) -> None:
    try:
        fd, name = tempfile.mkstemp(prefix=".rayflex-probe-", dir=parent)
    except OSError as e:
        reason = e.strerror or type(e).__name__
        raise OutputError(f"{flag} {path}: cannot write in {parent}: {reason}") from None
    os.close(fd)
    os.unlink(name)


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


# ---------------------------------------------------------------------------------------------
# writers (by extension)

def save_image(image: np.ndarray, path) -> None:
    """Write an (h, w, 3) or (h, w, 4) uint8 image in the format its extension names."""
    path = Path(path)
    fmt = image_extensions().get(path.suffix.lower())
    if fmt is None:
        raise OutputError(f"{path}: unknown image extension {path.suffix or '(none)'!r}")
    img = Image.fromarray(np.asarray(image, np.uint8))
    if img.mode == "RGBA" and fmt in ("JPEG", "PPM", "PCX", "SGI"):
        img = img.convert("RGB")
    img.save(str(path), format=fmt)


def jsonable(x):
    """numpy scalars/arrays and tuples to plain JSON types; non-finite floats to null."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    return x


def write_json(doc, path) -> None:
    """Write ``doc`` (numpy values allowed) as indented JSON."""
    with open(path, "w") as f:
        f.write(json.dumps(jsonable(doc), indent=2) + "\n")
