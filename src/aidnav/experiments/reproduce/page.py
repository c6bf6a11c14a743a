"""Pages of a reproduction: ``DIR/report.html`` per seed (self-contained: figures embedded as base64 PNG),
``DIR/index.html`` for ``aidnav reproduce all``, and the paper-vs-ours table on the console.

Each table shows quantity, unit, paper, ours, the Monte Carlo standard error of ours, target, verdict
(holds / fails / unresolved), whether the row is a SPEC acceptance target, and the reason where it does
not hold. The layout fits a 1400-px window: the body is at most 1300 px wide, tables scroll inside their
own box, long text wraps and images scale down.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
import shutil
import subprocess
from pathlib import Path

from .summary import STRUCTURAL_NULL, count_verdicts, target_shown

__all__ = ["write_seed_page", "write_index", "print_summary", "report_folder", "ReproductionError",
           "browser_layout", "browser_check", "is_reproduction", "CHROMIUM_FLAGS"]

CSS = """
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,"Noto Sans CJK SC","Noto Sans CJK JP",
"Noto Sans SC","Source Han Sans SC","Microsoft YaHei","PingFang SC",sans-serif;margin:1.5em auto;
max-width:1300px;color:#222;padding:0 1em}
h1,h2,p,li,figcaption{overflow-wrap:anywhere}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.8em}
.scroll{max-width:100%;overflow-x:auto}
table{border-collapse:collapse;font-size:.82em;margin:.5em 0;max-width:100%}
th,td{border:1px solid #ccc;padding:.25em .45em;vertical-align:top;white-space:nowrap}
th{background:#f0f0f0;text-align:left}td.num{text-align:right}
td.q,td.t,td.r{white-space:normal;overflow-wrap:anywhere}
td.q{min-width:16em;max-width:34em}td.t{max-width:18em;font-family:monospace;font-size:.95em}
td.r{min-width:12em;max-width:26em;color:#555}
.holds{background:#dfd;color:#060}.fails{background:#fdd;color:#900;font-weight:bold}
.unresolved{background:#ffe9b3;color:#7a5200;font-weight:bold}
.structural-null{background:#e6e6f5;color:#336;font-weight:bold}
td.g{white-space:nowrap;text-align:right}td.g small{color:#666}
.chk{display:block;color:#046;font-size:.95em}
.note{color:#444;font-size:.88em;max-width:100%}figure{margin:1em 0;max-width:100%}
img{max-width:100%;height:auto;border:1px solid #eee}figcaption{font-size:.85em;color:#555}
.sens{border-left:4px solid #88a;padding-left:.6em}
"""


class ReproductionError(ValueError):
    """The directory does not hold a reproduction (no ``summary.json`` of a seed)."""


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if isinstance(x, bool):
        return "yes" if x else "no"
    return f"{float(x):.4g}"


def _e(x) -> str:
    return html.escape(str(x))


def _counts(doc: dict) -> dict:
    return doc.get("verdicts") or count_verdicts(doc.get("tables", []))


def _target_cell(r: dict) -> str:
    t = r.get("target")
    if not t:
        return '<td class="t">–</td>'
    shown = r.get("check") or target_shown(r)
    chk = f'<span class="chk">{_e(shown)}</span>' if shown and shown != t else ""
    return f'<td class="t">{_e(t)}{chk}</td>'


def _kind(r: dict) -> str:
    return "SPEC" if r.get("spec") else ("–" if not r.get("target") else
                                         ("paper" if r.get("paper") is not None else "check"))


def _row_html(r: dict) -> str:
    v = r.get("verdict")
    vcell = '<td class="num">–</td>' if v is None else f'<td class="{v}">{v}</td>'
    return ("<tr>" f'<td class="q">{_e(r["quantity"])}</td><td>{_e(r.get("unit", ""))}</td>'
            f'<td class="num">{_fmt(r.get("paper"))}</td><td class="num">{_fmt(r.get("ours"))}</td>'
            f'<td class="num">{_fmt(r.get("stderr"))}</td><td class="num">{_e(r.get("runs") or "–")}</td>'
            f'{_target_cell(r)}{vcell}<td>{_kind(r)}</td>'
            f'<td class="r">{_e(r.get("reason") or "")}</td></tr>')


_HEAD = ["quantity", "unit", "paper", "ours", "std. error", "runs", "target (with its numbers)", "verdict",
         "kind", "reason"]


def _grid_cell(r: dict | None) -> str:
    if r is None:
        return "<td>–</td>"
    se = r.get("stderr")
    se_t = f" ± {_fmt(se)}" if se is not None else ""
    v = r.get("verdict")
    cls = f' class="g {v}"' if v else ' class="g"'
    tip = _e(f"{r['quantity']} [{r.get('unit', '')}]" + (f"; {r['target']}: {r.get('check')}" if v else ""))
    paper = "" if r.get("paper") is None else f'{_fmt(r.get("paper"))} <small>paper</small><br>'
    return (f'<td{cls} title="{tip}">{paper}'
            f"<b>{_fmt(r.get('ours'))}</b>{_e(se_t)} <small>ours</small></td>")


def _grid_html(t: dict) -> str:
    g = t["grid"]
    rows = t["rows"]
    head = "<th></th>" + "".join(f"<th>{_e(c)}</th>" for c in g["cols"])
    body = "".join("<tr><th>" + _e(lab) + "</th>" + "".join(
        _grid_cell(None if i is None else rows[i]) for i in idx) + "</tr>"
        for lab, idx in zip(g["rows"], g["index"], strict=True))
    units = sorted({rows[i].get("unit", "") for idx in g["index"] for i in idx if i is not None})
    runs = sorted({rows[i].get("runs") for idx in g["index"] for i in idx if i is not None and
                   rows[i].get("runs")})
    foot = (f'<p class="note">each cell: the paper\'s number above ours ± its Monte Carlo standard error; '
            f"unit {_e(', '.join(u for u in units if u) or '-')}; runs {_e(', '.join(map(str, runs)) or '–')}"
            "; the verdict colours a cell that has a target (hover for it).</p>")
    return (f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'
            + foot)


def _table_html(t: dict) -> str:
    head = "".join(f"<th>{h}</th>" for h in _HEAD)
    rows = t["rows"]
    grid = ""
    if t.get("grid"):
        grid = _grid_html(t)
        used = {i for idx in t["grid"]["index"] for i in idx if i is not None}
        rows = [r for i, r in enumerate(rows) if i not in used]
    body = "".join(_row_html(r) for r in rows)
    kind = t.get("kind", "results")
    cls = ' class="sens"' if kind == "sensitivity" else ""
    label = {"sensitivity": " (sensitivity)", "setting": " (setting)"}.get(kind, "")
    table = (f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'
             if rows else "")
    return (f"<section{cls}><h2>{_e(t['name'])}{label}</h2><p>{_e(t.get('caption', ''))}</p>{grid}{table}"
            "</section>")


def _counts_line(c: dict) -> str:
    s, p = c["spec"], c["other"]
    sn = ("; " + ", ".join(f"{x[STRUCTURAL_NULL]} structural-null" for x in (s,)) if s.get(STRUCTURAL_NULL)
          else "")
    po = f", {p[STRUCTURAL_NULL]} structural-null" if p.get(STRUCTURAL_NULL) else ""
    return (f"SPEC rows: {s['holds']} hold, {s['fails']} fail, {s['unresolved']} unresolved{sn}; other rows "
            f"with a target: {p['holds']} hold, {p['fails']} fail, {p['unresolved']} unresolved{po}")


def _runs_line(doc: dict) -> str:
    rs = sorted({r["runs"] for t in doc["tables"] for r in t["rows"] if r.get("runs")})
    if not rs:
        return f"Monte Carlo runs: {doc.get('runs')}"
    span = f"{rs[0]}" if len(rs) == 1 else f"{rs[0]}–{rs[-1]}"
    return (f"Monte Carlo runs: {doc.get('runs')} per case by default; the rows use {span} "
            f"({', '.join(map(str, rs))}), each row states its own")


def seed_page_html(out: Path, doc: dict) -> str:
    """The HTML text of one seed's report (figures read from ``out`` and embedded)."""
    parts = [f"<h1>Seed {_e(doc['seed'])}: {_e(doc['title'])}</h1>"]
    meta = [("base seed", doc.get("base_seed")),
            ("aidnav version", doc.get("aidnav_version")), ("run time [s]", doc.get("elapsed_s"))]
    parts.append("<p>" + _e(_runs_line(doc)) + " · "
                 + " · ".join(f"{_e(k)}: {_e(v)}" for k, v in meta if v is not None) + "</p>")
    parts.append(f"<p><b>{_e(_counts_line(_counts(doc)))}</b></p>")
    parts.append('<p class="note">verdict: <i>holds</i> / <i>fails</i> from the target; <i>unresolved</i> '
                 "when a trend or ordering between Monte Carlo statistics is within 2 standard errors; "
                 "<i>structural-null</i> when the compared effect is exactly zero by construction (no run "
                 "can move it). The target column repeats the target with its numbers. "
                 "kind: SPEC = acceptance target of the specification; paper = comparison with the "
                 "paper's number; check = a check of our own; – = configuration echo or informative number "
                 "(no target). Schema: "
                 "docs/reproduce_schema.md.</p>")
    bad = [(t["name"], r) for t in doc["tables"] for r in t["rows"]
           if r.get("spec") and r.get("verdict") != "holds"]
    if bad:
        parts.append("<h2>SPEC rows that do not hold</h2><ul>" + "".join(
            f"<li><b>{_e(n)}</b>: {_e(r['quantity'])} — {_e(r['verdict'])}: {_e(r.get('reason'))}</li>"
            for n, r in bad) + "</ul>")
    for t in doc["tables"]:
        if t.get("kind") != "sensitivity":
            parts.append(_table_html(t))
    sens = [t for t in doc["tables"] if t.get("kind") == "sensitivity"]
    if sens:
        parts.append("<h2>Sensitivity studies</h2>")
        parts += [_table_html(t) for t in sens]
    if doc.get("figures"):
        parts.append("<h2>Figures</h2>")
    for f in doc.get("figures", []):
        p = out / f
        if not p.is_file():
            parts.append(f'<p class="fails">figure {_e(f)} missing</p>')
            continue
        b64 = base64.b64encode(p.read_bytes()).decode("ascii")
        parts.append(f'<figure><img alt="{_e(f)}" src="data:image/png;base64,{b64}">'
                     f"<figcaption>{_e(f)}</figcaption></figure>")
    if doc.get("notes"):
        parts.append("<h2>Notes: errata followed, choices, disclosures</h2><ul>"
                     + "".join(f'<li class="note">{_e(n)}</li>' for n in doc["notes"]) + "</ul>")
    return _page(f"aidnav reproduction of seed {doc['seed']}", "".join(parts))


def _page(title: str, body: str) -> str:
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{_e(title)}</title>'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<style>{CSS}</style></head><body>{body}</body></html>\n")


def write_seed_page(out_dir, doc: dict | None = None) -> Path:
    """Write ``out_dir/report.html`` from ``doc`` (default: ``out_dir/summary.json``); return its path."""
    out = Path(out_dir)
    if doc is None:
        doc = load_summary(out)
    path = out / "report.html"
    path.write_text(seed_page_html(out, doc), encoding="utf-8")
    return path


def load_summary(out: Path) -> dict:
    p = Path(out) / "summary.json"
    if not p.is_file():
        raise ReproductionError(f"{out}: no summary.json (run `aidnav reproduce SEED -o DIR` first)")
    doc = json.loads(p.read_text())
    if "seed" not in doc or "tables" not in doc:
        raise ReproductionError(f"{p}: not a reproduction summary (no seed/tables)")
    return doc


def write_index(out_dir, outcomes=None) -> Path:
    """Write ``out_dir/index.html``: one line per seed sub-directory (``seed_XXX``) with its verdict
    counts and a link to its report; ``outcomes`` (from :func:`aidnav.experiments.reproduce.reproduce`)
    adds the seeds that could not be reproduced."""
    out = Path(out_dir)
    rows = []
    seen = set()
    for d in sorted(out.glob("seed_*")):
        if not (d / "summary.json").is_file():
            continue
        doc = load_summary(d)
        seen.add(doc["seed"])
        c = _counts(doc)
        s = c["spec"]
        cls = "holds" if s["fails"] == 0 and s["unresolved"] == 0 else "fails"
        rows.append(f'<tr><td><a href="{_e(d.name)}/report.html">seed {_e(doc["seed"])}</a></td>'
                    f'<td class="q">{_e(doc["title"])}</td><td class="num">{_e(doc.get("runs"))}</td>'
                    f'<td class="{cls}">{s["holds"]} / {s["fails"]} / {s["unresolved"]}</td>'
                    f'<td class="num">{c["other"]["holds"]} / {c["other"]["fails"]} / '
                    f'{c["other"]["unresolved"]}</td><td class="num">{_fmt(doc.get("elapsed_s"))}</td></tr>')
    for o in outcomes or ():
        if not o.ok and o.seed not in seen:
            rows.append(f"<tr><td>seed {_e(o.seed)}</td><td class=\"r\" colspan=\"5\">cannot be reproduced "
                        f"yet: {_e(o.reason)}</td></tr>")
    if not rows:
        raise ReproductionError(f"{out}: no seed_XXX/summary.json")
    head = "".join(f"<th>{h}</th>" for h in ("seed", "title", "runs", "SPEC rows hold / fail / unresolved",
                                             "other rows hold / fail / unresolved", "run time [s]"))
    body = (f"<h1>aidnav reproductions</h1><div class=\"scroll\"><table><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table></div>")
    path = out / "index.html"
    path.write_text(_page("aidnav reproductions", body), encoding="utf-8")
    return path


def report_folder(directory) -> list[Path]:
    """Write the pages of a reproduction folder: ``report.html`` for a seed folder, or each
    ``seed_XXX/report.html`` and ``index.html`` for a ``reproduce all`` folder. Returns the paths written.
    Raises :class:`ReproductionError` when the folder holds no reproduction."""
    d = Path(directory)
    if (d / "summary.json").is_file():
        return [write_seed_page(d)]
    subs = [s for s in sorted(d.glob("seed_*")) if (s / "summary.json").is_file()]
    if not subs:
        raise ReproductionError(f"{d}: not a reproduction folder (no summary.json, no seed_XXX/summary.json)")
    return [write_seed_page(s) for s in subs] + [write_index(d)]


def is_reproduction(directory) -> bool:
    """True when ``directory`` holds a seed summary (and no campaign manifest) or seed_XXX summaries."""
    d = Path(directory)
    if (d / "manifest.json").is_file():
        return False
    return (d / "summary.json").is_file() or any((s / "summary.json").is_file() for s in d.glob("seed_*"))


def print_summary(console, doc: dict, tables=None, sensitivity: bool = False) -> None:
    """The paper-vs-ours tables of ``doc`` on a rich console (data strings are not read as markup):
    ``tables`` (names; None: all), the sensitivity studies only with ``sensitivity`` (they are in
    report.html)."""
    from rich.table import Table  # lazy: rich is heavy to import
    from rich.text import Text  # lazy: rich is heavy to import

    skipped = 0
    for t in doc["tables"]:
        if tables is not None and t["name"] not in tables:
            continue
        if t.get("kind") == "sensitivity" and not sensitivity:
            skipped += 1
            continue
        tab = Table(title=Text(f"seed {doc['seed']} · {t['name']}: {t['caption']}"), title_justify="left")
        for c, just in (("quantity", "left"), ("unit", "left"), ("paper", "right"), ("ours", "right"),
                        ("±se", "right"), ("runs", "right"), ("target", "left"), ("verdict", "left")):
            tab.add_column(c, justify=just, overflow="fold")
        style = {"holds": "green", "fails": "bold red", "unresolved": "yellow", STRUCTURAL_NULL: "blue"}
        for r in t["rows"]:
            v = r.get("verdict")
            vt = Text("" if v is None else (v + (" (SPEC)" if r.get("spec") else "")), style=style.get(v, ""))
            tab.add_row(Text(r["quantity"]), Text(r.get("unit", "")), Text(_fmt(r.get("paper"))),
                        Text(_fmt(r.get("ours"))), Text(_fmt(r.get("stderr"))),
                        Text(str(r.get("runs") or "")),
                        Text(" → ".join(x for x in (r.get("target"), r.get("check")) if x)
                             if r.get("check") != r.get("target") else (r.get("target") or "")),
                        vt)
        console.print(tab)
    if skipped:
        console.print(Text(f"seed {doc['seed']}: {skipped} sensitivity tables in report.html"))
    console.print(Text(f"seed {doc['seed']}: {_counts_line(_counts(doc))}"))


_LAYOUT_JS = (
    '<script>window.addEventListener("load",()=>{let w=0;for(const e of document.querySelectorAll("body *"))'
    '{let p=e.parentElement,clip=false;while(p){const o=getComputedStyle(p).overflowX;if(o!=="visible")'
    '{clip=true;break}p=p.parentElement}const r=e.getBoundingClientRect().right;if(!clip&&r>w)w=r}'
    'document.body.setAttribute("data-maxright",String(w));document.body.setAttribute("data-scrollw",'
    'String(document.documentElement.scrollWidth));document.body.setAttribute("data-imgs",String('
    '[...document.images].filter(i=>i.complete&&i.naturalWidth>0).length))});</script>')


def browser_layout(page, work_dir, width: int = 1400):
    """Open ``page`` (a report.html) in headless Chromium with a ``width``-px window: returns (largest right
    edge of an element not clipped by a scrolling box [px], the document's scroll width [px], images
    decoded, path of a screenshot in ``work_dir``), or None when Chromium is not installed. For tests."""
    found = [shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")]
    exe = next((f for f in found if f), None)
    if exe is None:
        return None
    Path(work_dir).mkdir(parents=True, exist_ok=True)
    probe = Path(work_dir) / "probe.html"
    probe.write_text(page.read_text().replace("</body>", _LAYOUT_JS + "</body>"))
    args = [exe, "--headless", "--no-sandbox", "--disable-gpu", f"--window-size={width},1000",
            "--virtual-time-budget=5000"]
    dom = subprocess.run(args + ["--dump-dom", probe.as_uri()], capture_output=True, text=True,
                         timeout=120).stdout
    shot = Path(work_dir) / "shot.png"
    subprocess.run(args + [f"--screenshot={shot}", page.as_uri()], capture_output=True, timeout=120)
    got = dict(re.findall(r'data-(maxright|scrollw|imgs)="([0-9.]+)"', dom))
    return float(got["maxright"]), float(got["scrollw"]), int(got["imgs"]), shot


#: the headless-Chromium flags of the page checks (a fresh --user-data-dir is added per call)
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--no-first-run", "--hide-scrollbars")

#: run at window "load": layout (widest element not inside a scrolling box, scroll width), every table and
#: image (visible: a non-zero box inside the document; images decoded) and the CJK glyphs of the page. The
#: glyph test draws each CJK character of the page, a second CJK character and a character no font has
#: (U+10FFFD, private use: always a missing-glyph box) on a canvas in the body's font: a character that
#: renders as a box draws the same pixels as that character, and two boxes draw the same pixels as each
#: other.
_CHECK_JS = r"""<script>window.addEventListener("load",()=>{
const W=window.innerWidth;let maxr=0;
for(const e of document.querySelectorAll("body *")){
 if(e.closest(".scroll")&&e.closest(".scroll")!==e)continue;
 const r=e.getBoundingClientRect();if(r.width===0&&r.height===0)continue;if(r.right>maxr)maxr=r.right;}
const vis=e=>{const r=e.getBoundingClientRect();return r.width>0&&r.height>0&&
 getComputedStyle(e).visibility!=="hidden"&&getComputedStyle(e).display!=="none";};
const tabs=[...document.querySelectorAll("table")];const imgs=[...document.images];
const txt=document.body.innerText;const cjk=[...new Set(txt.match(/[\u3400-\u9fff]/g)||[])];
const font=getComputedStyle(document.body).fontFamily;
const draw=ch=>{const c=document.createElement("canvas");c.width=48;c.height=48;
 const x=c.getContext("2d");x.font="40px "+font;x.fillStyle="#000";x.textBaseline="top";x.fillText(ch,2,2);
 return Array.from(x.getImageData(0,0,48,48).data).join(",");};
const tofu=draw(String.fromCodePoint(0x10FFFD));const bad=[];
for(const ch of cjk){const d=draw(ch);const other=draw(ch==="\u7cbe"?"\u5ea6":"\u7cbe");
 if(d===tofu||d===other)bad.push(ch);}
const res={width:W,docheight:document.documentElement.scrollHeight,maxright:maxr,
 scrollw:document.documentElement.scrollWidth,tables:tabs.length,tables_visible:tabs.filter(vis).length,
 imgs:imgs.length,imgs_ok:imgs.filter(i=>i.complete&&i.naturalWidth>0&&vis(i)).length,
 cjk:cjk.join(""),cjk_boxes:bad.join(""),font:font};
const p=document.createElement("pre");p.id="reproduce-check";p.style.display="none";
p.textContent=JSON.stringify(res);document.body.appendChild(p);});</script>"""


def browser_check(page, work_dir, width: int = 1400, height: int = 1000):
    """Open ``page`` (a report.html) in headless Chromium (a fresh profile, ``CHROMIUM_FLAGS``) with a
    ``width`` × ``height`` window; write a full-page screenshot ``work_dir/<stem>_shot.png``. Returns a dict:
    ``maxright`` (largest right edge of an element outside a scrolling box, px), ``scrollw`` (the document's
    scroll width, px), ``tables`` / ``tables_visible``, ``imgs`` / ``imgs_ok`` (decoded and visible),
    ``cjk`` (the CJK characters of the page), ``cjk_boxes`` (those that render as a missing-glyph box),
    ``font``, ``shot`` (the screenshot's path) — or None when Chromium is not installed. For tests."""
    import json as _json  # lazy: only the checks need it here
    import tempfile  # lazy: only the checks need it

    found = [shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")]
    exe = next((f for f in found if f), None)
    if exe is None:
        return None
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    page = Path(page)
    probe = work / f"{page.parent.name}_{page.stem}_check.html"
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", _CHECK_JS + "</body>"),
                     encoding="utf-8")
    shot = work / f"{page.parent.name}_{page.stem}_shot.png"
    with tempfile.TemporaryDirectory(dir=work) as prof:
        args = [exe, *CHROMIUM_FLAGS, f"--user-data-dir={prof}", f"--window-size={width},{height}",
                "--virtual-time-budget=10000"]
        dom = subprocess.run(args + ["--dump-dom", probe.as_uri()], capture_output=True, text=True,
                             timeout=180).stdout
    m = re.search(r'<pre id="reproduce-check"[^>]*>(.*?)</pre>', dom, re.S)
    if m is None:
        raise RuntimeError(f"{page}: the page check did not run in Chromium")
    res = _json.loads(html.unescape(m.group(1)))
    # the full page: a window as tall as the document (capped), so that every table and figure is on it
    tall = min(max(height, int(res.get("docheight", 0)) or height * 8), 30000)
    with tempfile.TemporaryDirectory(dir=work) as prof:
        subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={prof}", f"--window-size={width},{tall}",
                        "--virtual-time-budget=10000", f"--screenshot={shot}", page.as_uri()],
                       capture_output=True, timeout=180)
    res["shot"] = shot
    return res
