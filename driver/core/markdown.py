"""The Markdown tables the commands and studies print: one header row, the separator, one line
per row, every cell between ``|`` and single spaces."""

from __future__ import annotations


def table(head, rows) -> str:
    """A Markdown table of column titles ``head`` and ``rows`` (sequences of cells, each already
    formatted as its text)."""
    return "\n".join(["| " + " | ".join(head) + " |", "|" + "---|" * len(head),
                      *("| " + " | ".join(row) + " |" for row in rows)])
