"""Building blocks of the self-contained HTML report: escaped text, tables, figures, links.

Every piece returns an :class:`Html` (text that is already safe to place in a page);
anything else handed to :func:`cell` or :func:`esc` is escaped with ``html.escape``.
Figures are embedded as ``data:image/png;base64`` URIs, so the page needs no other file;
links to result files are relative to the report's folder.
"""

from __future__ import annotations

import base64
import html
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class Html(str):
    """Markup that is already escaped (a ``str`` subclass, so it joins like text)."""

    __slots__ = ()


@dataclass(frozen=True)
class Section:
    """One titled part of the page.

    Attributes:
        anchor: Its id (for the table of contents).
        title: Its heading (plain text; escaped when rendered).
        body: Its content.
    """

    anchor: str
    title: str
    body: Html


def esc(value: object) -> Html:
    """Return ``value`` as text escaped for HTML (an :class:`Html` is passed through)."""
    if isinstance(value, Html):
        return value
    return Html(html.escape(str(value), quote=True))


def join(parts: Iterable[str]) -> Html:
    """Concatenate pieces of markup (each escaped unless it is an :class:`Html`)."""
    return Html("".join(esc(p) for p in parts))


def tag(name: str, body: object = "", **attrs: object) -> Html:
    """Return ``<name attrs>body</name>``; attribute values are escaped (``cls`` → ``class``)."""
    text = "".join(
        f' {"class" if k == "cls" else k.replace("_", "-")}="{esc(v)}"'
        for k, v in attrs.items()
        if v is not None
    )
    return Html(f"<{name}{text}>{esc(body)}</{name}>")


def fmt(value: object, digits: int = 4) -> str:
    """Format a value for a table: floats to ``digits`` significant figures, None/NaN as —."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if 1e4 <= abs(value) < 1e9:  # stiffnesses: 124602 reads better than 1.246e+05
            return f"{value:.0f}"
        return f"{value:.{digits}g}"
    return str(value)


def pct(value: object, digits: int = 1) -> str:
    """Format a relative value (0.05) as a signed percentage (+5.0 %); None as —."""
    if not isinstance(value, int | float) or not math.isfinite(value):
        return "—"
    return f"{100.0 * value:+.{digits}f} %"


def cell(value: object, *, header: bool = False) -> Html:
    """Return one ``<td>`` (numbers right-aligned) or ``<th>``."""
    if header:
        return tag("th", value if isinstance(value, Html) else fmt(value))
    numeric = isinstance(value, int | float) and not isinstance(value, bool)
    return tag("td", value if isinstance(value, Html) else fmt(value), cls="n" if numeric else None)


def table(
    headers: Sequence[object], rows: Iterable[Sequence[object]], *, caption: str | None = None
) -> Html:
    """Return a table; cells are formatted with :func:`fmt` unless they are :class:`Html`."""
    head = tag("tr", join(cell(h, header=True) for h in headers))
    body = join(tag("tr", join(cell(v) for v in row)) for row in rows)
    # a <caption> is as narrow as its table; a paragraph above it wraps at the page width
    cap = tag("p", caption, cls="cap") if caption else ""
    return join([cap, tag("table", join([tag("thead", head), tag("tbody", body)]))])


def kv_table(pairs: Iterable[tuple[str, object]]) -> Html:
    """Return a two-column table of name → value (values formatted with :func:`fmt`)."""
    rows = join(tag("tr", join([tag("th", k), cell(v)])) for k, v in pairs)
    return tag("table", tag("tbody", rows), cls="kv")


def scroll(body: Html) -> Html:
    """Wrap long content in a box that scrolls on screen and prints in full."""
    return tag("div", body, cls="scroll")


def png_data_uri(path: Path) -> str | None:
    """Return the PNG file as a ``data:`` URI, or None if it is missing or not a PNG."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if not data.startswith(PNG_SIGNATURE):
        return None
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def png_size(path: Path) -> tuple[int, int] | None:
    """Return (width, height) in pixels from a PNG's header, or None if it is not a PNG."""
    try:
        with path.open("rb") as fh:
            head = fh.read(24)
    except OSError:
        return None
    if not head.startswith(PNG_SIGNATURE) or len(head) < 24:
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def figure(path: Path, caption: str, *, wide: bool = False) -> Html:
    """Return a figure with the PNG embedded, or a note naming the file if it cannot be read.

    In a grid of figures, a picture more than twice as wide as high takes a whole row.
    """
    uri = png_data_uri(path)
    size = png_size(path)
    if uri is None or size is None:
        return tag("p", f"figure not available: {path} (missing or not a PNG)", cls="missing")
    w, h = size
    img = Html(f'<img src="{esc(uri)}" alt="{esc(caption)}" width="{w}" height="{h}">')
    cls = " ".join(c for c, on in (("wide", wide), ("span", w > 2.0 * h)) if on) or None
    return tag("figure", join([img, tag("figcaption", caption)]), cls=cls)


def figures(items: Iterable[tuple[Path, str]]) -> Html:
    """Return the existing figures of ``items`` side by side (nothing if none exists)."""
    present = [figure(p, c) for p, c in items if p.is_file()]
    return tag("div", join(present), cls="grid") if present else Html("")


def link(target: Path, report_dir: Path, label: str | None = None) -> Html:
    """Return a link to a result file, relative to the report's folder (plain text if missing)."""
    text = label or target.name
    if not target.exists():
        return tag("span", f"{text} (missing)", cls="missing")
    rel = Path(os.path.relpath(target.resolve(), report_dir.resolve())).as_posix()
    return tag("a", text, href=quote(rel))


def links(items: Iterable[tuple[str, Path]], report_dir: Path) -> Html:
    """Return links to those of ``items`` (label, path) that exist, separated by spaces."""
    return Html(" ".join(link(p, report_dir, lbl) for lbl, p in items if p.exists()))


def verdict(passed: bool | None) -> Html:
    """Return a coloured pass/FAIL mark."""
    if passed is None:
        return Html("—")
    return tag("span", "pass" if passed else "FAIL", cls="pass" if passed else "fail")


def cards(items: Iterable[tuple[str, str]]) -> Html:
    """Return a row of headline numbers (label, value)."""
    return tag(
        "div",
        join(tag("div", join([tag("b", v), tag("span", k)]), cls="card") for k, v in items),
        cls="cards",
    )


CSS = """
:root{--fg:#1b1f24;--muted:#5b6470;--line:#d3d9e0;--head:#eef2f6;--accent:#1f5f99;
--bad:#b3261e;--good:#1e7a3c}
*{box-sizing:border-box}
body{margin:0;color:var(--fg);background:#fff;
font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif}
main{max-width:1180px;margin:0 auto;padding:20px 28px 60px}
header.top{border-bottom:3px solid var(--accent);margin-bottom:1em;padding-bottom:.6em}
h1{font-size:1.6em;margin:0 0 .2em}
h2{font-size:1.25em;border-bottom:1px solid var(--line);padding-bottom:.2em;margin:1.8em 0 .6em}
h3{font-size:1.05em;margin:1.2em 0 .4em}
.sub{color:var(--muted);margin:0}
nav.toc{font-size:.92em;margin:.6em 0;display:flex;flex-wrap:wrap;gap:.2em 1.2em}
nav.toc a{white-space:nowrap}
a{color:var(--accent)}
table{border-collapse:collapse;margin:.5em 0 1em;font-size:.9em}
p.cap{color:var(--muted);margin:.8em 0 .2em;break-after:avoid}
th,td{border:1px solid var(--line);padding:.25em .55em;text-align:left;vertical-align:top}
th{background:var(--head);font-weight:600}
td.n{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
tbody tr:nth-child(even) td{background:#fafbfc}
table.kv th{width:16em}
table.kv td.n{text-align:left}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:.6em 0 1em}
.card{border:1px solid var(--line);border-left:4px solid var(--accent);border-radius:4px;
padding:.4em .9em;min-width:150px}
.card b{display:block;font-size:1.25em;font-variant-numeric:tabular-nums}
.card span{color:var(--muted);font-size:.85em}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(400px,1fr));gap:14px;
align-items:start}
figure{margin:.4em 0 1em;break-inside:avoid}
figure img{display:block;max-width:100%;height:auto;border:1px solid var(--line)}
figure.wide img{max-height:560px;width:auto}
.grid figure.span{grid-column:1/-1}
.grid figure.span img{max-height:420px;width:auto}
figcaption{color:var(--muted);font-size:.88em;margin-top:.25em}
.pass{color:var(--good);font-weight:600}
.fail{color:var(--bad);font-weight:600}
.missing{color:var(--bad)}
.note{color:var(--muted);font-size:.92em}
.scroll{max-height:440px;overflow:auto;border:1px solid var(--line);margin-bottom:1em}
.scroll table{margin:0}
pre{background:#f5f7f9;border:1px solid var(--line);padding:.7em;overflow:auto;font-size:.84em;
white-space:pre-wrap;overflow-wrap:anywhere}
footer{margin-top:3em;color:var(--muted);font-size:.85em}
@media print{
  @page{margin:14mm}
  body{font-size:10pt}
  main{max-width:none;padding:0}
  nav.toc{display:none}
  .scroll{max-height:none;overflow:visible;border:0}
  h2,h3{break-after:avoid}
  tr,figure,.card{break-inside:avoid}
  .grid{grid-template-columns:repeat(2,1fr)}
  figure.wide img,.grid figure.span img{max-height:none;max-width:100%}
  a{color:inherit;text-decoration:none}
}
"""
