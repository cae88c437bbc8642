"""Write the reference section of docs/api.md from the docstrings of the Python API.

    python tools/api_doc.py          # rewrite the section after "## Reference"
    python tools/api_doc.py --check  # exit 1 if the page's section differs

The names are ``driver.__all__`` (what ``import driver`` gives) and ``FRAME_NAMES`` (whole
workload frames, in the modules that load their heavy dependencies). Each entry is the name, its
signature (or value, for a constant) and its docstring, so the page says what the code says.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "api.md"
HEADING = "## Reference"
FRAME_NAMES = ("driver.design.DesignPoint", "driver.render.render", "driver.render.RenderResult")


def _entry(qualname: str, obj) -> str:
    if inspect.isclass(obj) or inspect.isroutine(obj):
        try:
            sig = str(inspect.signature(obj))
        except (TypeError, ValueError):
            sig = "(...)"
        kind = "class " if inspect.isclass(obj) else ""
        doc = inspect.getdoc(obj) or ""
        return f"### `{qualname}`\n\n```\n{kind}{qualname.rsplit('.', 1)[1]}{sig}\n```\n\n" \
               f"```text\n{doc}\n```\n"
    name = qualname.rsplit(".", 1)[1]
    if getattr(obj, "names", None):                         # a structured numpy dtype
        fields = "\n".join(f"  {f}: {obj.fields[f][0].str}"
                           + (f" {obj.fields[f][0].shape}" if obj.fields[f][0].shape else "")
                           for f in obj.names)
        return f"### `{qualname}`\n\nA numpy structured dtype, {obj.itemsize} bytes a row:\n\n" \
               f"```text\n{fields}\n```\n"
    return f"### `{qualname}`\n\n`{name} = {obj!r}`\n"


def reference() -> str:
    """The section's text: one entry per name, ``driver``'s in ``__all__`` order."""
    sys.path.insert(0, str(ROOT))
    import driver
    parts = [f"{HEADING}\n\nGenerated from the docstrings by `python tools/api_doc.py`.\n"]
    parts += [_entry(f"driver.{name}", getattr(driver, name)) for name in driver.__all__]
    for qual in FRAME_NAMES:
        module, name = qual.rsplit(".", 1)
        parts.append(_entry(qual, getattr(importlib.import_module(module), name)))
    return "\n".join(parts)


def split(text: str) -> tuple[str, str]:
    """(the page before the reference section, the section)."""
    at = text.index(f"\n{HEADING}\n") + 1
    return text[:at], text[at:]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    head, section = split(PAGE.read_text())
    want = reference()
    if "--check" in argv:
        if section != want:
            print(f"{PAGE}: the reference differs from the docstrings; run "
                  "python tools/api_doc.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(head + want)
    return 0


if __name__ == "__main__":
    sys.exit(main())
