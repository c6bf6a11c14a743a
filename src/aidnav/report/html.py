"""Self-contained HTML pages: shared machinery of the campaign report (``aidnav report``) and the run
page (``run.html`` of ``aidnav process`` / ``aidnav tight``).

Everything a page needs is inside it: the style sheet is inline and figures are embedded as base64
PNG ``data:`` URIs, so a page can be mailed or archived as one file. No script, no external resource.

Layout rule (checked in headless Chromium by the tests): at a 1400-px window no element is wider
than the window. Wide data tables scroll inside their own box (``div.scroll``); key/value tables
(:func:`kv_table`) wrap their values instead of scrolling them out of sight; images scale down.
"""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path

import numpy as np

__all__ = ["CSS", "DPI", "escape", "fmt", "table", "kv_table", "png_b64", "img_tag", "img_file_tag", "page"]

#: Resolution of embedded figures [dots per inch].
DPI = 100

escape = html.escape

CSS = """
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em auto;
max-width:1300px;color:#222;padding:0 1em;overflow-wrap:break-word}
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.8em}
h3{font-size:1.05em}
table{border-collapse:collapse;font-size:.85em;margin:.5em 0}
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:right;white-space:nowrap}
th{background:#f0f0f0;white-space:normal}td:first-child,th:first-child{text-align:left}
table.kv{max-width:100%}
table.kv td{white-space:normal;overflow-wrap:anywhere;text-align:left}
table.kv td:first-child{white-space:nowrap;font-weight:600;background:#fafafa}
.scroll{overflow-x:auto;max-width:100%}.bad{background:#fdd;color:#900;font-weight:bold}
.good{background:#dfd;color:#060}
.note{color:#555;font-size:.85em}img{max-width:100%;height:auto;display:block;margin:.5em 0}
code{background:#f4f4f4;padding:0 .2em;overflow-wrap:anywhere}
pre{white-space:pre-wrap;overflow-wrap:anywhere;background:#f7f7f7;padding:.5em;font-size:.8em}
ul.events li{overflow-wrap:anywhere}
"""


def fmt(x) -> str:
    """Number for a table cell: ``–`` for None/NaN/inf, yes/no for booleans, ints as is, 4 significant
    digits otherwise; any other value as ``str``."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        return "–" if not math.isfinite(float(x)) else f"{float(x):.4g}"
    return str(x)


def _cells(r, tag: str = "td") -> str:
    cells = []
    for c in r:
        if isinstance(c, tuple):  # (html, css class)
            cells.append(f'<{tag} class="{c[1]}">{c[0]}</{tag}>')
        else:
            cells.append(f"<{tag}>{html.escape(str(c))}</{tag}>")
    return "".join(cells)


def table(header: list[str], rows: list[list], cls: str = "") -> str:
    """A data table inside a horizontally scrolling box. Cells are escaped text, or ``(html, css class)``
    tuples for preformatted cells (e.g. ``("consistent", "good")``)."""
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + _cells(r) + "</tr>" for r in rows)
    return f'<div class="scroll"><table class="{cls}"><thead><tr>{h}</tr></thead><tbody>' + body + \
        "</tbody></table></div>"


def kv_table(rows: list[list]) -> str:
    """A key/value table (no header): the values wrap (long paths, host strings) so that nothing is
    pushed out of the window."""
    body = "".join("<tr>" + _cells(r) + "</tr>" for r in rows)
    return f'<table class="kv"><tbody>{body}</tbody></table>'


def png_b64(fig, dpi: int = DPI) -> str:
    """A matplotlib figure as base64-encoded PNG text."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def img_tag(b64: str, alt: str, mime: str = "image/png") -> str:
    """``<img>`` element with the image embedded as a data URI."""
    return f'<img alt="{html.escape(alt)}" src="data:{mime};base64,{b64}">'


_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml",
         ".gif": "image/gif"}


def img_file_tag(path, alt: str | None = None) -> str:
    """``<img>`` element embedding the image file ``path`` (PNG, JPEG, SVG or GIF) as a data URI.

    Raises ``ValueError`` for another file type and ``FileNotFoundError`` when the file is missing."""
    path = Path(path)
    mime = _MIME.get(path.suffix.lower())
    if mime is None:
        raise ValueError(f"{path}: cannot embed a {path.suffix or 'suffix-less'} file as an image "
                         f"(expected one of {', '.join(sorted(_MIME))})")
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return img_tag(data, alt if alt is not None else path.stem.replace("_", " "), mime)


def page(title: str, parts: list[str]) -> str:
    """A complete HTML document with the shared style sheet."""
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>"
            + "\n".join(parts) + "</body></html>")
