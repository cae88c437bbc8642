"""Numbers in words for what the tool prints: ``plural(1, "run")`` is "1 run", ``plural(0,
"edge tie")`` "0 edge ties" (the counts the command line prints in words go through it, so that
none reads "1 runs"), and ``cell``, a text table's value or its mark for none."""

from __future__ import annotations


def plural(n, word: str, many: str | None = None, fmt: str = "") -> str:
    """``n`` and ``word``, in the plural (``many``, default ``word + "s"``) unless ``n`` is 1;
    ``fmt``: the number's format (e.g. "," for thousands)."""
    return f"{format(n, fmt)} {word if n == 1 else many or word + 's'}"


MISSING = "-"       # a table's cell without a value (a ray type's utilization in a one-kernel frame)


def cell(value, spec: str = "") -> str:
    """A table cell: ``value`` in format ``spec``, or ``MISSING`` for None or NaN (every text
    table of the tool shows a missing value the same way)."""
    if value is None or (isinstance(value, float) and value != value):
        return MISSING
    return format(value, spec)
