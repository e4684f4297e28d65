"""The HTML renderer: one self-contained file (inline CSS, figures as base64 PNG)."""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Sequence
from html.parser import HTMLParser
from typing import Any

from balancer_id.report.blocks import (
    Block,
    Cell,
    Paragraph,
    Preformatted,
    Section,
    Subheading,
    Table,
)
from balancer_id.report.plots import figure_png


def escape(text: object) -> str:
    """Text made safe inside HTML (quotes too).

    Parameters
    ----------
    text : object
        Shown as ``str(text)``.

    Returns
    -------
    str
    """
    return html.escape(str(text), quote=True)


def anchor(title: str) -> str:
    """The ``id`` of a section's heading (``s-`` and the title's lowercase words).

    Parameters
    ----------
    title : str

    Returns
    -------
    str
    """
    return "s-" + (re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-") or "section")


_e, _anchor = escape, anchor

CSS = """
:root { --ink:#1d2330; --mute:#5b6474; --line:#d9dee7; --head:#eef2f7; --accent:#0b5cad; }
* { box-sizing: border-box; }
body { font: 14px/1.45 -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif;
       color: var(--ink); margin: 0; background: #f6f7f9; }
header { background: #14213d; color: #fff; padding: 22px 36px 16px; }
header h1 { margin: 0 0 4px; font-size: 24px; font-weight: 600; }
header .sub { margin: 0; color: #c9d3e6; }
header .meta { margin: 6px 0 0; color: #93a1bb; font-size: 12px; }
nav { background: #fff; border-bottom: 1px solid var(--line); padding: 8px 36px; font-size: 13px; }
nav ol { margin: 0; padding: 0; list-style: none; display: flex; flex-wrap: wrap; gap: 4px 18px; }
nav a { color: var(--accent); text-decoration: none; }
main { max-width: 1180px; margin: 0 auto; padding: 8px 36px 36px; }
section { background: #fff; border: 1px solid var(--line); border-radius: 6px;
          padding: 6px 22px 16px; margin: 18px 0; }
h2 { font-size: 18px; border-bottom: 2px solid var(--accent); padding-bottom: 4px; }
h3 { font-size: 15px; margin: 16px 0 4px; color: #14213d; }
p { margin: 8px 0; }
pre { background: #f3f5f8; border-left: 3px solid var(--accent); padding: 8px 12px;
      font: 13px/1.4 "DejaVu Sans Mono", Menlo, Consolas, monospace; overflow-x: auto; }
table { border-collapse: collapse; margin: 10px 0 4px; font-size: 13px; max-width: 100%; }
caption { caption-side: bottom; text-align: left; color: var(--mute); font-size: 12px;
          padding-top: 4px; max-width: 900px; }
th, td { border: 1px solid var(--line); padding: 4px 9px; vertical-align: top; }
td { overflow-wrap: anywhere; }
th { background: var(--head); text-align: left; font-weight: 600; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.strong { font-weight: 600; }
td.good { background: #e3f4e8; } td.warn { background: #fff3d6; } td.bad { background: #fbe0dd; }
td.dim { color: #9aa3b2; }
figure { margin: 14px 0; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { color: var(--mute); font-size: 12px; max-width: 900px; }
.cards { display: flex; flex-wrap: wrap; gap: 10px; margin: 12px 0; }
.card { border: 1px solid var(--line); border-radius: 6px; padding: 8px 14px; min-width: 130px;
        background: #f9fbfd; }
.card.alt { background: #f5f7f2; }
.card .k { color: var(--mute); font-size: 12px; }
.card .v { font-size: 20px; font-weight: 600; font-variant-numeric: tabular-nums; }
.card .pm { font-size: 13px; font-weight: 400; color: var(--mute); }
.card .u { color: var(--mute); font-size: 12px; }
.alert { background: #fff3d6; border: 1px solid #f0d38a; padding: 6px 10px; border-radius: 4px; }
footer { color: var(--mute); font-size: 12px; text-align: center; padding: 0 0 24px; }
@media print {
  body { background: #fff; } header { background: #fff; color: #000; padding: 0; }
  header .sub, header .meta { color: #333; } nav { display: none; }
  section { border: none; padding: 0; break-inside: auto; } figure { break-inside: avoid; }
  main { padding: 0; max-width: none; }
}
"""

_NUMERIC = re.compile(r"^[+\-−]?(\d|\.\d)[\d.,eE+\-× ]*(±\s*[\d.eE+\-]+)?( \(held\))?$")


def _html_cell(cell: str | Cell, tag: str = "td") -> str:
    text, style = (cell.text, cell.style) if isinstance(cell, Cell) else (cell, "")
    classes = [style] if style else []
    if tag == "td" and _NUMERIC.match(text.strip()):
        classes.append("num")
    cls = f' class="{" ".join(classes)}"' if classes else ""
    return f"<{tag}{cls}>{_e(text)}</{tag}>"


def _html_table(table: Table) -> str:
    head = "".join(f"<th>{_e(c)}</th>" for c in table.columns)
    body = "".join("<tr>" + "".join(_html_cell(c) for c in row) + "</tr>\n" for row in table.rows)
    cap = f"<caption>{_e(table.caption)}</caption>" if table.caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>\n{body}</tbody></table>\n"


def _png(figure: Any) -> bytes:
    if isinstance(figure, bytes | bytearray):
        return bytes(figure)
    return figure_png(figure)


def _html_block(block: Block, counter: list[int]) -> str:
    if isinstance(block, Paragraph):
        return f"<p>{_e(block.text)}</p>\n"
    if isinstance(block, Preformatted):
        return f"<pre>{_e(block.text)}</pre>\n"
    if isinstance(block, Subheading):
        return f"<h3>{_e(block.text)}</h3>\n"
    if isinstance(block, Table):
        return _html_table(block)
    counter[0] += 1
    data = base64.b64encode(_png(block.figure)).decode("ascii")
    label = f"Figure {counter[0]}"
    cap = f"<figcaption><b>{label}.</b> {_e(block.caption)}</figcaption>"
    return (
        f'<figure><img alt="{_e(label + ". " + block.caption)}" '
        f'src="data:image/png;base64,{data}">{cap}</figure>\n'
    )


def _render_html(
    title: str, subtitle: str, sections: Sequence[Section], meta: dict[str, str]
) -> str:
    counter = [0]
    nav = "".join(
        f'<li><a href="#{_anchor(s.title)}">{k}. {_e(s.title)}</a></li>'
        for k, s in enumerate(sections, 1)
    )
    body = []
    for k, s in enumerate(sections, 1):
        parts = [f'<section id="{_anchor(s.title)}">\n<h2>{k}. {_e(s.title)}</h2>\n']
        if s.html:
            parts.append(s.html + "\n")
        parts += [_html_block(b, counter) for b in s.all_blocks()]
        parts.append("</section>\n")
        body.append("".join(parts))
    stamp = f"balancer-id {meta['balancer-id']} · {meta['date']}"
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f'<meta name="generator" content="{_e(stamp)}">\n'
        f"<title>{_e(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
        f"<header><h1>{_e(title)}</h1>"
        + (f'<p class="sub">{_e(subtitle)}</p>' if subtitle else "")
        + f'<p class="meta">{_e(stamp)}</p></header>\n'
        f"<nav><ol>{nav}</ol></nav>\n<main>\n{''.join(body)}</main>\n"
        f"<footer>{_e(title)} · {_e(stamp)}</footer>\n</body>\n</html>\n"
    )


class _TextOnly(HTMLParser):
    """The text of an HTML fragment (for the PDF)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.parts: list[str] = []

    def handle_data(self, data: str) -> None:
        self.parts.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag in {"p", "div", "li", "tr", "h3", "h4", "br", "table"}:
            self.parts.append("\n")


def _html_text(fragment: str) -> str:
    parser = _TextOnly()
    parser.feed(fragment)
    parser.close()
    lines = (" ".join(line.split()) for line in "".join(parser.parts).splitlines())
    return "\n".join(line for line in lines if line)


# --------------------------------------------------------------------------------------
# PDF
# --------------------------------------------------------------------------------------
