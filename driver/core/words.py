"""Numbers in words for what the tool prints: ``plural(1, "run")`` is "1 run", ``plural(0,
"edge tie")`` "0 edge ties" (every count the command line, the tables and the plots print goes
through it, so that none reads "1 runs")."""

from __future__ import annotations


def plural(n, word: str, many: str | None = None, fmt: str = "") -> str:
    """``n`` and ``word``, in the plural (``many``, default ``word + "s"``) unless ``n`` is 1;
    ``fmt``: the number's format (e.g. "," for thousands)."""
    return f"{format(n, fmt)} {word if n == 1 else many or word + 's'}"
