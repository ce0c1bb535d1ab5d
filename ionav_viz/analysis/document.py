"""A report as a document of headings, tables, paragraphs and lists, and its two renderers.

Every report (a drive's, a fleet's, a comparison's, the error against outage length) builds a
:class:`Document` from its numbers; :func:`to_text` and :func:`to_markdown` are the only places
that lay one out, so a table looks the same in every report. (JSON is each report's ``to_dict``.)

As text a table's key columns are left-aligned and its values right-aligned under a rule; a table
wider than the width gets wrapped headers, then is split into blocks of columns
(:func:`aligned`), and a prose line wider than it is wrapped with a hanging indent. As Markdown a
table is a pipe table and each heading a bold line or a ``#`` heading.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass


@dataclass(frozen=True)
class Code:
    """Inline code in a line (a command to copy): in backticks as Markdown, as it is as text."""

    text: str


#: A line of prose: plain text, or parts of which some are :class:`Code`.
Line = str | tuple[str | Code, ...]


@dataclass(frozen=True)
class Heading:
    """A heading.

    Attributes:
        text: the heading.
        level: as Markdown, 0 a line in bold, 1 ``#``, 2 ``##``.
        note: what follows the heading on its line, not part of it (not in bold).
        lead_in: as text, it ends with a colon (it introduces the table under it).
    """

    text: str
    level: int = 0
    note: str = ""
    lead_in: bool = False


@dataclass(frozen=True)
class Table:
    """A table of text cells (every row as long as the header).

    Attributes:
        header, rows: the column names and the cells, row by row.
        left: how many columns are keys: left-aligned as text (the rest, the values, right-aligned)
            and repeated in each block of columns a narrow width splits the table into.
        align: as Markdown, the value columns are marked right-aligned (``---:``).
        strong_first: as Markdown, the first column's cells are in bold.
        repeat_keys: as Markdown, a key cell left blank under the row above repeats that row's
            (each row whole; as text the blank reads as "the same").
    """

    header: list[str]
    rows: list[list[str]]
    left: int = 1
    align: bool = False
    strong_first: bool = False
    repeat_keys: bool = False


@dataclass(frozen=True)
class Paragraphs:
    """Lines of prose: one line each as text, each a paragraph of its own as Markdown."""

    lines: list[Line]


@dataclass(frozen=True)
class Items:
    """A list, one line per item: as Markdown bulleted (``- ``); ``numbered`` ``1. `` in both."""

    items: list[Line]
    numbered: bool = False


Block = Heading | Table | Paragraphs | Items


@dataclass(frozen=True)
class Document:
    """A report's blocks in order.

    Attributes:
        blocks: the headings, tables, paragraphs and lists.
        spaced: as text, a blank line between blocks (Markdown always has one).
        hang: as text wider than the width, a line is wrapped with a hanging indent of this many
            spaces (None: lines are left as they are; tables are fitted either way).
    """

    blocks: list[Block]
    spaced: bool = True
    hang: int | None = 2


def to_text(doc: Document, width: int | None = None) -> str:
    """``doc`` as plain text fitted into ``width`` columns (None: no limit, one line per row)."""
    out = _joined([_text_lines(b, width) for b in doc.blocks], doc.spaced)
    if width is not None and doc.hang is not None:
        out = [_folded(line, width, doc.hang) for line in out]
    return "\n".join(out) + "\n"


def to_markdown(doc: Document) -> str:
    """``doc`` as Markdown."""
    return "\n".join(_joined([_markdown_lines(b) for b in doc.blocks], True)) + "\n"


def _joined(parts: list[list[str]], spaced: bool) -> list[str]:
    """The blocks' lines one after the other (a block with none left out), with a blank line
    between blocks if ``spaced``."""
    out: list[str] = []
    for lines in (p for p in parts if p):
        out += ([""] if out and spaced else []) + lines
    return out


def _inline(line: Line, markdown: bool) -> str:
    if isinstance(line, str):
        return line
    return "".join((f"`{p.text}`" if markdown else p.text) if isinstance(p, Code) else p for p in line)


def _text_lines(block: Block, width: int | None) -> list[str]:
    if isinstance(block, Heading):
        return [block.text + (f" {block.note}" if block.note else "") + (":" if block.lead_in else "")]
    if isinstance(block, Table):
        return aligned(block.header, block.rows, block.left, width)
    if isinstance(block, Paragraphs):
        return [_inline(line, False) for line in block.lines]
    return [(f"{k}. " if block.numbered else "") + _inline(item, False) for k, item in enumerate(block.items, 1)]


def _markdown_lines(block: Block) -> list[str]:
    if isinstance(block, Heading):
        head = f"**{block.text}**" if block.level == 0 else f"{'#' * block.level} {block.text}"
        return [head + (f" {block.note}" if block.note else "")]
    if isinstance(block, Table):
        return _markdown_table(block)
    if isinstance(block, Paragraphs):
        return [line for text in block.lines for line in ("", _inline(text, True))][1:]
    return [(f"{k}. " if block.numbered else "- ") + _inline(item, True) for k, item in enumerate(block.items, 1)]


def _markdown_table(table: Table) -> list[str]:
    rows = [list(r) for r in table.rows]
    if table.repeat_keys:
        for above, row in zip(rows, rows[1:]):
            row[: table.left] = [cell or up for cell, up in zip(row[: table.left], above[: table.left])]
    if table.strong_first:
        rows = [[f"**{c}**" if j == 0 and c else c for j, c in enumerate(r)] for r in rows]
    n = len(table.header)
    rule = ("|" + "|".join("---" if j < table.left else "---:" for j in range(n)) + "|" if table.align
            else "|" + "---|" * n)
    return ["| " + " | ".join(table.header) + " |", rule, *("| " + " | ".join(r) + " |" for r in rows)]


def _folded(line: str, width: int, hang: int) -> str:
    """A line wider than ``width`` wrapped, its continuation lines indented by ``hang`` spaces."""
    if len(line) <= width:
        return line
    return "\n".join(textwrap.wrap(line, width, subsequent_indent=" " * hang, break_on_hyphens=False))


def aligned(header: list[str], rows: list[list[str]], left: int, width: int | None = None) -> list[str]:
    """A plain-text table: the first ``left`` columns (the keys) left-aligned, the rest right-aligned.

    Wider than ``width``, the header cells are wrapped onto several lines (a column as wide as its
    values or its longest word), and if that is still too wide the value columns are split into
    blocks, one under the other, each repeating the key columns. A table with fewer than two value
    columns cannot be split: it is returned with its header wrapped, wider than ``width``.
    """
    lines = _table([header], rows, left)
    if width is None or max(map(len, lines)) <= width:
        return lines
    for lines_per_header in (2, 3, 4, 99):  # as few header lines as fit
        header_lines = _wrapped_header(header, rows, lines_per_header)
        lines = _table(header_lines, rows, left)
        if max(map(len, lines)) <= width:
            return lines
    keys, values = list(range(min(left, len(header)))), list(range(min(left, len(header)), len(header)))
    if len(values) < 2:
        return lines
    header_lines = _wrapped_header(header, rows, 2)
    col_w = [max(len(r[j]) for r in header_lines + rows) for j in range(len(header))]
    room = width - sum(col_w[j] + 2 for j in keys)
    for n_blocks in range(2, len(values) + 1):  # as few blocks as fit, of equal column counts
        size = -(-len(values) // n_blocks)
        blocks = [values[i : i + size] for i in range(0, len(values), size)]
        if all(sum(col_w[j] + 2 for j in block) - 2 <= room for block in blocks):
            break
    out: list[str] = []
    for b, block in enumerate(blocks):
        cols = keys + block
        kept = [r for r in rows if any(r[j] for j in block)]  # a row with nothing in this block is left out of it
        heads = [line for line in ([h[j] for j in cols] for h in header_lines) if any(line)]
        out += ([""] if b else []) + _table(heads, [[r[j] for j in cols] for r in kept], len(keys))
    return out


def _wrapped_header(header: list[str], rows: list[list[str]], n_lines: int) -> list[list[str]]:
    """Header cells wrapped onto about ``n_lines`` lines (a column never narrower than its values or
    its longest word), bottom-aligned: one list of cells per header line."""
    widths = [max([len(r[j]) for r in rows] + [len(w) for w in h.split()] + [-(-len(h) // n_lines)])
              for j, h in enumerate(header)]
    wrapped = [textwrap.wrap(h, widths[j], break_on_hyphens=False) or [""] for j, h in enumerate(header)]
    depth = max(map(len, wrapped))
    padded = [[""] * (depth - len(w)) + w for w in wrapped]
    return [[cell[i] for cell in padded] for i in range(depth)]


def _table(header_lines: list[list[str]], rows: list[list[str]], left: int) -> list[str]:
    widths = [max(len(r[j]) for r in header_lines + rows) for j in range(len(header_lines[0]))]

    def line(r: list[str]) -> str:
        return "  ".join(c.ljust(w) if j < left else c.rjust(w) for j, (c, w) in enumerate(zip(r, widths))).rstrip()
    return [line(h) for h in header_lines] + ["  ".join("-" * w for w in widths)] + [line(r) for r in rows]
