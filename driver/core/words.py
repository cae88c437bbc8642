"""Numbers in words for what the tool prints: ``plural(1, "run")`` is "1 run", ``plural(0,
"edge tie")`` "0 edge ties" (the counts the command line prints in words go through it, so that
none reads "1 runs"), ``cell``, a text table's value or its mark for none, and ``wrap``, a
plot's title broken between words only."""

from __future__ import annotations

import re
import textwrap


def plural(n, word: str, many: str | None = None, fmt: str = "") -> str:
    """``n`` and ``word``, in the plural (``many``, default ``word + "s"``) unless ``n`` is 1;
    ``fmt``: the number's format (e.g. "," for thousands)."""
    return f"{format(n, fmt)} {word if n == 1 else many or word + 's'}"


MISSING = "-"       # a table's cell without a value (a ray type's utilization, one-kernel frame)


def cell(value, spec: str = "") -> str:
    """A table cell: ``value`` in format ``spec``, or ``MISSING`` for None or NaN (every text
    table of the tool shows a missing value the same way)."""
    if value is None or (isinstance(value, float) and value != value):
        return MISSING
    return format(value, spec)


_NUMBER_AND_UNIT = re.compile(r"(?<=\d) (?=[^\W\d])")         # "32 KiB", "246.2 B/cycle"


def wrap(title: str, width: int = 110) -> str:
    """A title broken into lines of at most ``width`` characters (a figure clips a long one),
    only between words: never inside a word, at its hyphen ("baseline-unified"), nor between
    a number and its unit ("32 KiB", "246.2 B/cycle")."""
    glued = _NUMBER_AND_UNIT.sub("\u00a0", title)          # a no-break space
    return "\n".join(textwrap.fill(part, width, break_long_words=False,
                                    break_on_hyphens=False)
                     for part in glued.split("\n"))
