"""A tiny document model rendered twice, as Markdown and as HTML (a jinja2 template), so ``report.md`` and
``index.html`` hold the same content: headings (with anchors and a table of contents), paragraphs, bullet lists,
tables (from DataFrames), images (PNG with an SVG beside it, paths relative to the report) and code.

Numbers are formatted per column (:func:`format_column`): 3 significant digits in plain positional notation
with thousands separators (``97,800``, ``4.85``, ``0.0127``), integers in full (``23,064``), so a column never
mixes ``1.32e+05`` with ``3877.2``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

__all__ = ["Document", "format_value", "format_column", "markdown_table", "slug", "image_fill"]

SIGNIFICANT = 3


def _number(value: float, significant: int = SIGNIFICANT) -> str:
    """``value`` rounded to ``significant`` digits, positional, thousands separators; ``0`` for 0."""
    if value == 0:
        return "0"
    magnitude = math.floor(math.log10(abs(value)))
    decimals = significant - 1 - magnitude
    rounded = round(value, decimals)  # negative decimals round to tens, hundreds...: 185,123 -> 185,000
    if decimals <= 0:
        return f"{rounded:,.0f}"
    return f"{rounded:,.{min(decimals, 12)}f}"


def format_value(value: Any) -> str:
    """A table cell: floats with 3 significant digits (positional), integers in full, NaN/None empty, bools yes/no."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value:,}"
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return _number(value)
    try:
        if pd.isna(value):
            return ""
    except (TypeError, ValueError):
        pass
    if hasattr(value, "item") and callable(value.item):  # numpy scalars
        try:
            return format_value(value.item())
        except (TypeError, ValueError):
            pass
    return str(value)


def format_column(column: pd.Series) -> list[str]:
    """Every cell of one column formatted the same way (:func:`format_value` with the column's dtype)."""
    if pd.api.types.is_bool_dtype(column):
        return [format_value(bool(v)) if not pd.isna(v) else "" for v in column]
    if pd.api.types.is_integer_dtype(column):
        return [f"{int(v):,}" for v in column]
    if pd.api.types.is_float_dtype(column):
        return [format_value(float(v)) for v in column]
    return [format_value(v) for v in column]


def _numeric(column: pd.Series) -> bool:
    return pd.api.types.is_numeric_dtype(column) and not pd.api.types.is_bool_dtype(column)


def _cell_md(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown_table(frame: pd.DataFrame) -> str:
    """A GitHub-flavoured Markdown table of ``frame`` (index dropped); numbers right-aligned, formatted per column."""
    if frame.empty:
        return "_(no rows)_"
    columns = [str(c) for c in frame.columns]
    numeric = [_numeric(frame[c]) for c in frame.columns]
    cells = [format_column(frame[c]) for c in frame.columns]
    lines = ["| " + " | ".join(columns) + " |", "|" + "|".join("---:" if n else "---" for n in numeric) + "|"]
    for i in range(len(frame)):
        lines.append("| " + " | ".join(_cell_md(cells[j][i]) for j in range(len(columns))) + " |")
    return "\n".join(lines)


def slug(text: str, taken: set[str] | None = None) -> str:
    """An HTML id for a heading: lower-case words joined by ``-``, unique within ``taken``."""
    base = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"
    name, n = base, 2
    while taken is not None and name in taken:
        name, n = f"{base}-{n}", n + 1
    if taken is not None:
        taken.add(name)
    return name


def _html_table(frame: pd.DataFrame) -> dict:
    """Header and rows of a table for the template: cells as ``(text, css class: "num", "short" or "long")``."""
    columns = [str(c) for c in frame.columns]
    numeric = [_numeric(frame[c]) for c in frame.columns]
    cells = [format_column(frame[c]) for c in frame.columns]
    rows = []
    for i in range(len(frame)):
        row = []
        for j in range(len(columns)):
            value = frame.iloc[i, j]
            number = numeric[j] or (isinstance(value, (int, float)) and not isinstance(value, bool))
            # Numbers and short text (codec names, configs) stay on one line; long notes wrap.
            row.append((cells[j][i], "num" if number else "short" if len(cells[j][i]) <= 32 else "long"))
        rows.append(row)
    return {"columns": columns, "rows": rows}


def image_fill(out: Path, caption: str, missing: str | None = None):
    """``fill`` of :meth:`Document.later` for a figure: its image (path made relative to the report folder ``out``)
    with ``caption``, or the ``missing`` paragraph (or nothing) when the figure function drew nothing (None)."""

    def fill(doc: "Document", path: Path | None) -> None:
        if path is not None:
            doc.image(Path(path).relative_to(out).as_posix(), caption)
        elif missing:
            doc.paragraph(missing)

    return fill


@dataclass
class Document:
    """Blocks of a report, in order; :meth:`markdown` and :meth:`html` render the same blocks."""

    title: str
    blocks: list[tuple[str, Any]] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("heading", (level, text)))

    def paragraph(self, text: str, *, strong: bool = False) -> None:
        self.blocks.append(("paragraph", (text, strong)))

    def bullets(self, items: list[str]) -> None:
        self.blocks.append(("bullets", list(items)))

    def table(self, frame: pd.DataFrame, caption: str | None = None) -> None:
        self.blocks.append(("table", (frame.reset_index(drop=True), caption)))

    def image(self, path: str, caption: str) -> None:
        """A figure (PNG path relative to the report); an SVG with the same stem beside it is linked."""
        self.blocks.append(("image", (path, caption)))

    def code(self, text: str) -> None:
        self.blocks.append(("code", text))

    def link(self, href: str, text: str) -> None:
        """A paragraph that is one link (``href`` relative to the report, e.g. a page beside it)."""
        self.blocks.append(("link", (href, text)))

    def later(self, result: Any, fill: Any) -> None:
        """A place for blocks known later: ``fill(document, result.result())`` adds them when :meth:`resolve` runs.

        ``result`` is a ``concurrent.futures.Future`` (a figure drawn in another process while the next sections
        are computed); the blocks land here, in the document's order, whatever order the results come in.
        """
        self.blocks.append(("later", (result, fill)))

    def resolve(self) -> None:
        """Wait for every :meth:`later` block and put its blocks in its place (:meth:`markdown` and :meth:`html` do it
        first: a place left unfilled would drop its figure without a word)."""
        blocks: list[tuple[str, Any]] = []
        for kind, value in self.blocks:
            if kind == "later":
                part = Document(self.title)
                value[1](part, value[0].result())
                part.resolve()
                blocks += part.blocks
            else:
                blocks.append((kind, value))
        self.blocks = blocks

    def markdown(self) -> str:
        self.resolve()
        out = [f"# {self.title}", ""]
        for kind, value in self.blocks:
            if kind == "heading":
                out += ["#" * value[0] + " " + value[1], ""]
            elif kind == "paragraph":
                out += [f"**{value[0]}**" if value[1] else value[0], ""]
            elif kind == "bullets":
                out += [f"- {item}" for item in value] + [""]
            elif kind == "table":
                frame, caption = value
                if caption:
                    out += [f"*{caption}*", ""]
                out += [markdown_table(frame), ""]
            elif kind == "image":
                svg = str(Path(value[0]).with_suffix(".svg"))
                out += [f"![{value[1]}]({value[0]})", "", f"*{value[1]}* ([SVG]({svg}))", ""]
            elif kind == "code":
                out += ["```", value, "```", ""]
            elif kind == "link":
                out += [f"[{value[1]}]({value[0]})", ""]
        return "\n".join(out)

    def html(self) -> str:
        """The document through ``templates/report.html.j2`` (autoescaped), with a table of contents."""
        from jinja2 import Environment, PackageLoader, select_autoescape

        self.resolve()
        env = Environment(loader=PackageLoader("mocapbench.experiments", "templates"),
                          autoescape=select_autoescape(["html", "j2"]), trim_blocks=True, lstrip_blocks=True)
        taken: set[str] = set()
        blocks, toc = [], []
        for kind, value in self.blocks:
            if kind == "heading":
                anchor = slug(value[1], taken)
                toc.append({"level": value[0], "text": value[1], "anchor": anchor})
                blocks.append({"kind": kind, "level": value[0], "text": value[1], "anchor": anchor})
            elif kind == "paragraph":
                blocks.append({"kind": kind, "text": value[0], "strong": value[1]})
            elif kind == "bullets":
                blocks.append({"kind": kind, "items": value})
            elif kind == "table":
                frame, caption = value
                blocks.append({"kind": kind, "caption": caption, "empty": frame.empty, **_html_table(frame)})
            elif kind == "image":
                blocks.append({"kind": kind, "src": value[0], "svg": str(Path(value[0]).with_suffix(".svg")),
                               "caption": value[1]})
            elif kind == "code":
                blocks.append({"kind": kind, "text": value})
            elif kind == "link":
                blocks.append({"kind": kind, "href": value[0], "text": value[1]})
        return env.get_template("report.html.j2").render(title=self.title, toc=toc, blocks=blocks)
