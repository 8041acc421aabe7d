"""A tiny document model rendered twice, as Markdown and as HTML, so ``report.md`` and ``index.html`` hold the same
content: headings, paragraphs, bullet lists, tables (from DataFrames) and images (PNG paths relative to the report)."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

__all__ = ["Document", "format_value", "markdown_table"]


def format_value(value: Any) -> str:
    """A table cell: floats with 4 significant digits (large ones without exponent), NaN/None as an empty cell."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        if value != 0 and (abs(value) >= 1e5 or abs(value) < 1e-3):
            return f"{value:.3g}"
        if abs(value) >= 100:
            return f"{value:,.0f}" if abs(value) >= 1e4 else f"{value:.1f}"
        return f"{value:.4g}"
    try:
        if pd.isna(value):
            return ""
    except (TypeError, ValueError):
        pass
    return str(value)


def _cell_md(value: Any) -> str:
    return format_value(value).replace("|", "\\|").replace("\n", " ")


def markdown_table(frame: pd.DataFrame) -> str:
    """A GitHub-flavoured Markdown table of ``frame`` (index dropped); numbers right-aligned."""
    if frame.empty:
        return "_(no rows)_"
    columns = [str(c) for c in frame.columns]
    numeric = [pd.api.types.is_numeric_dtype(frame[c]) and not pd.api.types.is_bool_dtype(frame[c]) for c in frame]
    lines = ["| " + " | ".join(columns) + " |", "|" + "|".join("---:" if n else "---" for n in numeric) + "|"]
    for row in frame.itertuples(index=False):
        lines.append("| " + " | ".join(_cell_md(v) for v in row) + " |")
    return "\n".join(lines)


def _html_table(frame: pd.DataFrame) -> str:
    if frame.empty:
        return "<p><em>(no rows)</em></p>"
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in frame.columns)
    body = []
    for row in frame.itertuples(index=False):
        cells = "".join(
            f"<td class='num'>{html.escape(format_value(v))}</td>"
            if isinstance(v, (int, float)) and not isinstance(v, bool)
            else f"<td>{html.escape(format_value(v))}</td>"
            for v in row
        )
        body.append(f"<tr>{cells}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


_STYLE = (
    "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0;font-size:90%}th,td{border:1px solid #ccc;padding:3px 6px}"
    "th{background:#f0f0f0}td.num{text-align:right;font-variant-numeric:tabular-nums}img{max-width:100%}"
    "code{background:#f4f4f4;padding:1px 3px}"
)


@dataclass
class Document:
    """Blocks of a report, in order; :meth:`markdown` and :meth:`html` render the same blocks."""

    title: str
    blocks: list[tuple[str, Any]] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("heading", (level, text)))

    def paragraph(self, text: str) -> None:
        self.blocks.append(("paragraph", text))

    def bullets(self, items: list[str]) -> None:
        self.blocks.append(("bullets", list(items)))

    def table(self, frame: pd.DataFrame, caption: str | None = None) -> None:
        self.blocks.append(("table", (frame.reset_index(drop=True), caption)))

    def image(self, path: str, caption: str) -> None:
        self.blocks.append(("image", (path, caption)))

    def code(self, text: str) -> None:
        self.blocks.append(("code", text))

    def markdown(self) -> str:
        out = [f"# {self.title}", ""]
        for kind, value in self.blocks:
            if kind == "heading":
                out += ["#" * value[0] + " " + value[1], ""]
            elif kind == "paragraph":
                out += [value, ""]
            elif kind == "bullets":
                out += [f"- {item}" for item in value] + [""]
            elif kind == "table":
                frame, caption = value
                if caption:
                    out += [f"*{caption}*", ""]
                out += [markdown_table(frame), ""]
            elif kind == "image":
                out += [f"![{value[1]}]({value[0]})", "", f"*{value[1]}*", ""]
            elif kind == "code":
                out += ["```", value, "```", ""]
        return "\n".join(out)

    def html(self) -> str:
        esc = html.escape
        out = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{esc(self.title)}</title>",
               f"<style>{_STYLE}</style></head><body><h1>{esc(self.title)}</h1>"]
        for kind, value in self.blocks:
            if kind == "heading":
                out.append(f"<h{value[0]}>{esc(value[1])}</h{value[0]}>")
            elif kind == "paragraph":
                out.append(f"<p>{esc(value)}</p>")
            elif kind == "bullets":
                out.append("<ul>" + "".join(f"<li>{esc(item)}</li>" for item in value) + "</ul>")
            elif kind == "table":
                frame, caption = value
                if caption:
                    out.append(f"<p><em>{esc(caption)}</em></p>")
                out.append(_html_table(frame))
            elif kind == "image":
                out.append(f"<figure><img src='{esc(value[0])}' alt='{esc(value[1])}'>"
                           f"<figcaption>{esc(value[1])}</figcaption></figure>")
            elif kind == "code":
                out.append(f"<pre><code>{esc(value)}</code></pre>")
        out.append("</body></html>")
        return "\n".join(out)
