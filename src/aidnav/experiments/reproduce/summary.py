"""Reproduction summaries: ``DIR/summary.json`` in the schema of ``docs/reproduce_schema.md``.

A row compares our value with the paper's and states a *target*; ``holds`` is **computed** from the
target, never typed in. A target is either

* an expression string over ``ours``, ``paper`` and any further named values passed as ``values``
  (numbers, + − × ÷ **, comparisons, ``and``/``or``/``not``, ``abs``, ``min``, ``max``, ``sqrt``), e.g.
  ``"ours <= 1.2 * paper"``, ``"abs(ours - paper) <= 0.1 * paper"``, ``"none / figure8 >= 5"``; or
* a :class:`Target`: a text shown in the table and a predicate ``fn(ours, paper) -> bool``.

Example::

    rows = [summary_row("heading std, none", "deg", ours=0.21, paper=0.2483,
                        target="none / figure8 >= 5", values={"none": 0.21, "figure8": 0.03})]
    write_summary(out_dir, seed="004", title="Transfer alignment", runs=10, base_seed=1,
                  tables=[summary_table("Table 4", "heading error std by manoeuvre", rows)],
                  figures=["fig2_heading_error.png"], notes=["follows §5.2 item 3"])
"""

from __future__ import annotations

import ast
import json
import math
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Target", "summary_row", "summary_table", "grid_table", "write_summary", "evaluate_target",
           "check_expression", "check_row", "count_verdicts", "SummaryError", "VERDICTS", "resolved_row",
           "target_shown", "STRUCTURAL_NULL"]


class SummaryError(ValueError):
    """A summary that does not follow the schema (missing keys, a target that cannot be evaluated)."""


@dataclass(frozen=True)
class Target:
    """A target given as code: ``text`` (shown) and ``fn(ours, paper) -> bool``."""

    text: str
    fn: Callable[[float | None, float | None], bool]


_BIN = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
        ast.Pow: operator.pow, ast.Mod: operator.mod}
_CMP = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge,
        ast.Eq: operator.eq, ast.NotEq: operator.ne}
_FUNCS = {"abs": abs, "min": min, "max": max, "sqrt": math.sqrt}


def _parse(expr: str) -> ast.Expression:
    try:
        tree = ast.parse(expr, mode="eval")
    except SyntaxError as e:
        raise SummaryError(f"target {expr!r}: not an expression ({e.msg})") from None
    return tree


def _names(node) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and n.id not in _FUNCS}


def _eval(node, env: Mapping[str, float]):
    if isinstance(node, ast.Expression):
        return _eval(node.body, env)
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.Name):
        if node.id not in env:
            raise SummaryError(f"unknown name {node.id!r}")
        v = env[node.id]
        if v is None:
            raise SummaryError(f"{node.id!r} has no value")
        return v
    if isinstance(node, ast.BinOp) and type(node.op) in _BIN:
        return _BIN[type(node.op)](_eval(node.left, env), _eval(node.right, env))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd, ast.Not)):
        v = _eval(node.operand, env)
        return -v if isinstance(node.op, ast.USub) else (+v if isinstance(node.op, ast.UAdd) else not v)
    if isinstance(node, ast.BoolOp):
        vals = [_eval(v, env) for v in node.values]
        return all(vals) if isinstance(node.op, ast.And) else any(vals)
    if isinstance(node, ast.Compare) and all(type(o) in _CMP for o in node.ops):
        left = _eval(node.left, env)
        for op, comp in zip(node.ops, node.comparators, strict=True):
            right = _eval(comp, env)
            if not _CMP[type(op)](left, right):
                return False
            left = right
        return True
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCS \
            and not node.keywords:
        return _FUNCS[node.func.id](*[_eval(a, env) for a in node.args])
    raise SummaryError(f"unsupported element {ast.dump(node)[:60]!r} in a target expression")


def check_expression(expr: str, names: set[str] | None = None) -> None:
    """Raise ValueError if ``expr`` is not a target expression or uses names outside ``names``."""
    tree = _parse(expr)
    for node in ast.walk(tree):
        ok = isinstance(node, (ast.Expression, ast.Name, ast.Load, ast.BinOp, ast.UnaryOp, ast.BoolOp,
                               ast.Compare, ast.Call, ast.And, ast.Or, ast.Not, ast.USub, ast.UAdd,
                               *_BIN, *_CMP)) or (isinstance(node, ast.Constant)
                                                   and isinstance(node.value, (int, float)))
        if not ok:
            raise SummaryError(f"target {expr!r}: unsupported element {type(node).__name__}")
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in _FUNCS):
            raise SummaryError(f"target {expr!r}: only {', '.join(_FUNCS)} may be called")
    if names is not None:
        unknown = _names(tree) - set(names)
        if unknown:
            raise SummaryError(f"target {expr!r}: unknown name(s) {', '.join(sorted(unknown))} "
                               f"(known: {', '.join(sorted(names))})")


def evaluate_target(target, ours, paper=None, values: Mapping[str, float] | None = None) -> bool:
    """Verdict of ``target`` (expression string or :class:`Target`) for ``ours`` and ``paper``."""
    if isinstance(target, Target):
        return bool(target.fn(ours, paper))
    if not isinstance(target, str):
        raise SummaryError(f"target must be an expression string or a Target, got {type(target).__name__}")
    env = {"ours": ours, "paper": paper, **(values or {})}
    check_expression(target, set(env))
    try:
        res = _eval(_parse(target), env)
    except SummaryError as e:
        raise SummaryError(f"target {target!r}: {e}") from None
    except (ArithmeticError, TypeError, ValueError) as e:
        raise SummaryError(f"target {target!r}: cannot be evaluated: {e}") from None
    if not isinstance(res, bool):
        raise SummaryError(f"target {target!r}: is not a comparison (gives {res!r})")
    return res


def _num(x):
    if x is None:
        return None
    x = float(x)
    return None if not math.isfinite(x) else x


#: the verdict of a compared effect that is exactly zero by construction (distance 0 from the boundary with a
#: standard error of 0: the runs cannot move it, more runs would not resolve it); not a failure of the runs
STRUCTURAL_NULL = "structural-null"
VERDICTS = ("holds", "fails", "unresolved", STRUCTURAL_NULL)


def _g(x) -> str:
    return "nan" if x is None else f"{x:.3g}"

#: how many standard errors separate a resolved trend from Monte Carlo noise
RESOLVE_SE = 2.0


def summary_row(quantity: str, unit: str, ours, paper=None, target=None,
                values: Mapping[str, float] | None = None, *, spec: bool = False, stderr=None,
                margin: tuple[float, float] | None = None, reason: str | None = None,
                runs: int | None = None) -> dict:
    """One row of a reproduction table (keys: see ``docs/reproduce_schema.md``).

    ``holds`` is the verdict of ``target`` (None without a target: a configuration echo or an informative
    number). ``spec``: True for an acceptance target of SPEC, False for a paper comparison (e.g. a
    factor-2 cell); a row without a target cannot be ``spec``. ``stderr``: Monte Carlo standard error of
    ``ours`` (None when ``ours`` is not a Monte Carlo statistic). ``margin = (d, se)``: for a trend or
    ordering between Monte Carlo statistics, the signed distance ``d`` of the compared statistic from the
    target's boundary and its standard error ``se``; the verdict is ``unresolved`` when
    ``|d| < 2 se``, and ``structural-null`` when ``d`` and ``se`` are both exactly 0 (an effect that is zero
    by construction). ``holds`` is True exactly when the verdict is ``holds``. ``reason``: why a row fails
    or is unresolved (a default is written when not given). ``runs``: the Monte Carlo runs behind ``ours``
    (None: the table's, see :func:`summary_table`; 0: not a Monte Carlo number, e.g. a formula check).
    """
    o, p = _num(ours), _num(paper)
    holds = None
    text = None
    verdict = None
    vals = {str(k): _num(v) for k, v in (values or {}).items()}
    if target is not None:
        text = target.text if isinstance(target, Target) else str(target)
        finite = o is not None and all(v is not None for v in vals.values())
        holds = evaluate_target(target, o, p, vals) if finite else False
    elif spec:
        raise SummaryError(f"row {quantity!r}: a spec row needs a target")
    mg = None
    if margin is not None:
        if target is None:
            raise SummaryError(f"row {quantity!r}: a margin without a target")
        d, se = (_num(margin[0]), _num(margin[1]))
        mg = {"value": d, "stderr": se}
    if holds is not None:
        verdict = _verdict(holds, mg)
        holds = verdict == "holds"
        if verdict != "holds" and not reason:
            if verdict == STRUCTURAL_NULL:
                reason = ("the compared effect is exactly zero by construction (distance 0 from the target's "
                          "boundary in every run, standard error 0): no number of runs resolves it")
            elif verdict == "unresolved" and mg["stderr"] is None:
                reason = "no Monte Carlo standard error (one run): the trend cannot be resolved"
            elif verdict == "unresolved":
                reason = (f"within {RESOLVE_SE:g} standard errors of the target's boundary "
                          f"(distance {_g(mg['value'])}, standard error {_g(mg['stderr'])}): the runs do "
                          "not resolve it")
            elif not finite:
                reason = "no value (not finite)"
            else:
                reason = f"ours = {o:.4g} does not meet {text}"
    row = {"quantity": str(quantity), "unit": str(unit), "paper": p, "ours": o, "stderr": _num(stderr),
           "target": text, "holds": holds, "verdict": verdict, "spec": bool(spec) and text is not None,
           "reason": None if verdict in (None, "holds") else str(reason), "margin": mg,
           "values": vals or None, "runs": None if runs is None else int(runs), "check": None}
    row["check"] = target_shown(row)
    if isinstance(target, Target):
        row["_fn"] = target.fn
    return row


def _verdict(holds: bool, margin: dict | None) -> str:
    if margin is not None:
        d, se = margin["value"], margin["stderr"]
        if d == 0 and se == 0:
            return STRUCTURAL_NULL
        if d is None or se is None or abs(d) < RESOLVE_SE * se:
            return "unresolved"
    return "holds" if holds else "fails"


def resolved_row(row: dict, runs: int, why: str = "") -> dict:
    """A spec trend stated at the resolution of ``runs`` runs: the row ``row`` (made with a ``margin``
    ``(d, se)``) becomes "resolved on the holding side": target ``d >= 2 * se`` over the values ``d``, ``se``
    (no margin). It holds when the trend is resolved and on its holding side; otherwise it ``fails`` with a
    reason that says whether the runs resolve the trend on its failing side or do not resolve it at all
    (the effect is then below what ``runs`` runs resolve: its distance from the boundary is below
    |d| + 2 se). Used for a spec row that the most runs the time budget allows leave within 2 standard
    errors: a spec row is never ``unresolved`` (issue 27). ``why``: the physics argument appended to the
    reason. A row without a margin, or whose margin is unknown, is returned unchanged."""
    mg = row.get("margin")
    if mg is None or mg["value"] is None or mg["stderr"] is None:
        return row
    d, se = mg["value"], mg["stderr"]
    k = RESOLVE_SE
    if d >= k * se:
        reason = None
    elif d <= -k * se:
        reason = (f"resolved on the failing side at {runs} runs: {_g(d)} ± {_g(se)} (1 se) from the boundary "
                  f"of {row['target']}")
    else:
        reason = (f"not resolvable at {runs} runs: the effect is {_g(d)} ± {_g(se)} (1 se) from the boundary "
                  f"of {row['target']}, i.e. within ±{_g(abs(d) + k * se)} of it (2 se); the trend is not "
                  "shown")
    if reason and why:
        reason = f"{reason}. {why}"
    return summary_row(f"{row['quantity']} [{row['target']}, resolved at {k:g} se over {runs} runs]",
                       row["unit"], row["ours"], row["paper"], f"d >= {k:g} * se", {"d": d, "se": se},
                       spec=row["spec"], stderr=row["stderr"], reason=reason, runs=row.get("runs") or runs)


def summary_table(name: str, caption: str, rows: list[dict], kind: str = "results",
                  runs: int | None = None) -> dict:
    """``{name, caption, kind, rows}``; ``kind``: "results", "setting" (configuration echoes) or
    "sensitivity" (a study of a choice the seed leaves open). ``runs``: the Monte Carlo runs of the rows
    that do not state their own (configuration echoes without a target or standard error keep none)."""
    if kind not in TABLE_KINDS:
        raise SummaryError(f"table {name!r}: kind must be one of {', '.join(TABLE_KINDS)}")
    out = []
    for r in rows:
        if runs is not None and r.get("runs") is None and (r.get("target") is not None
                                                           or r.get("stderr") is not None
                                                           or kind != "setting"):
            r = dict(r, runs=int(runs))
        out.append(r)
    return {"name": str(name), "caption": str(caption), "kind": kind, "rows": out}


def grid_table(name: str, caption: str, cells: Mapping[tuple[str, str], dict], row_labels, col_labels,
               extra_rows=(), kind: str = "results", runs: int | None = None) -> dict:
    """A table shaped like the paper's: ``cells[(row label, column label)]`` is the row (of
    :func:`summary_row`) shown in that cell (paper value, ours ± se, verdict when it has a target);
    ``extra_rows`` (predicates, informative numbers) follow as an ordinary table. The summary keeps every
    row; ``grid`` = ``{"rows": row labels, "cols": column labels, "index": [[row index or null]]}``."""
    rows = list(cells.values()) + list(extra_rows)
    keys = list(cells)
    index = [[keys.index((r, c)) if (r, c) in cells else None for c in col_labels] for r in row_labels]
    t = summary_table(name, caption, rows, kind, runs)
    t["grid"] = {"rows": [str(r) for r in row_labels], "cols": [str(c) for c in col_labels], "index": index}
    return t


TABLE_KINDS = ("results", "setting", "sensitivity")
_ROW_KEYS = ("quantity", "unit", "paper", "ours", "stderr", "target", "holds", "verdict", "spec", "reason",
             "margin", "values", "runs", "check")


def _fmt_num(x: float) -> str:
    return f"{x:.4g}"


def target_shown(row: Mapping) -> str | None:
    """The target with its numbers: every name (``ours``, ``paper``, the ``values``) replaced by its value,
    e.g. ``lo <= ours <= hi`` → ``0.95 <= 1.02 <= 1.05``; None without a target, the target itself when it
    is code (:class:`Target`)."""
    t = row.get("target")
    if t is None:
        return None
    env = {"ours": row.get("ours"), "paper": row.get("paper"), **(row.get("values") or {})}
    try:
        names = _names(_parse(t))
    except SummaryError:
        return t

    def sub(m):
        k = m.group(0)
        if k in names and k in env:
            v = env[k]
            return "–" if v is None else _fmt_num(v)
        return k

    return re.sub(r"[A-Za-z_][A-Za-z0-9_]*", sub, t)


def check_row(r: Mapping, where: str = "") -> None:
    """Raise :class:`SummaryError` unless the row follows the schema and its ``holds`` and ``verdict`` are
    those of its target (re-evaluated here from ``ours``, ``paper`` and ``values``)."""
    q = f"{where}row {r.get('quantity', '?')!r}"
    missing = [k for k in _ROW_KEYS if k not in r]
    if missing:
        raise SummaryError(f"{q}: missing {missing} (make rows with summary_row)")
    if r["target"] is None:
        if r["holds"] is not None or r["verdict"] is not None:
            raise SummaryError(f"{q}: holds without a target")
        if r["spec"]:
            raise SummaryError(f"{q}: a spec row needs a target")
        if r["margin"] is not None:
            raise SummaryError(f"{q}: a margin without a target")
        return
    if not isinstance(r["holds"], bool):
        raise SummaryError(f"{q}: holds must be computed (a bool)")
    if not isinstance(r["spec"], bool):
        raise SummaryError(f"{q}: spec must be a bool")
    fn = r.get("_fn")
    try:
        if r["ours"] is None or any(v is None for v in (r["values"] or {}).values()):
            expect = False
        elif fn is not None:
            expect = bool(fn(r["ours"], r["paper"]))
        else:
            expect = evaluate_target(r["target"], r["ours"], r["paper"], r["values"] or {})
    except SummaryError as e:
        raise SummaryError(f"{q}: its target cannot be checked: {e}") from None
    mg = r["margin"]
    if mg is not None and (not isinstance(mg, Mapping) or set(mg) != {"value", "stderr"}):
        raise SummaryError(f"{q}: margin must be {{value, stderr}}")
    v = _verdict(expect, mg)
    if r["verdict"] != v:
        raise SummaryError(f"{q}: verdict {r['verdict']!r} disagrees with its target {r['target']!r} and "
                           f"margin ({v!r}; ours = {r['ours']}, paper = {r['paper']}: {expect})")
    if r["holds"] != (v == "holds"):
        raise SummaryError(f"{q}: holds = {r['holds']} but the verdict is {v!r} (holds must be verdict == "
                           "'holds')")
    if v != "holds" and not (isinstance(r["reason"], str) and r["reason"].strip()):
        raise SummaryError(f"{q}: a row that is {v} needs a reason")


def write_summary(out_dir, *, seed: str, title: str, runs: int, base_seed: int, tables: list[dict],
                  figures: list[str] = (), notes: list[str] = (), aidnav_version: str | None = None,
                  extra: Mapping | None = None) -> Path:
    """Write ``out_dir/summary.json`` (schema: ``docs/reproduce_schema.md``) and return its path.

    Every row is checked with :func:`check_row`: a row whose ``holds`` disagrees with its target (or
    whose verdict disagrees with its holds and margin, or that lacks a key) raises :class:`SummaryError`
    and nothing is written. ``extra``: further top-level keys (e.g. ``elapsed_s``).
    """
    if aidnav_version is None:
        import aidnav  # lazy: only on this branch

        aidnav_version = aidnav.__version__
    out_tables = []
    for t in tables:
        for k in ("name", "caption", "rows"):
            if k not in t:
                raise SummaryError(f"table {t.get('name', '?')!r}: missing key {k!r}")
        kind = t.get("kind", "results")
        if kind not in TABLE_KINDS:
            raise SummaryError(f"table {t['name']!r}: kind must be one of {', '.join(TABLE_KINDS)}")
        rows = []
        for r in t["rows"]:
            r = {"runs": None, **r}
            r["check"] = target_shown(r)
            check_row(r, f"table {t['name']!r}, ")
            rows.append({k: r[k] for k in _ROW_KEYS})
        tab = {"name": t["name"], "caption": t["caption"], "kind": kind, "rows": rows}
        if t.get("grid") is not None:
            tab["grid"] = t["grid"]
        out_tables.append(tab)
    doc = {"seed": str(seed), "title": str(title), "aidnav_version": aidnav_version, "runs": int(runs),
           "base_seed": int(base_seed), "tables": out_tables, "figures": [str(f) for f in figures],
           "notes": [str(n) for n in notes], "verdicts": count_verdicts(out_tables)}
    for k, v in (extra or {}).items():
        if k in doc:
            raise SummaryError(f"extra key {k!r} is a summary key")
        doc[k] = v
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "summary.json"
    tmp = out / "summary.json.tmp"
    tmp.write_text(json.dumps(doc, indent=2, allow_nan=False))
    tmp.replace(path)
    return path


def count_verdicts(tables: list[dict]) -> dict:
    """``{"spec": {holds, fails, unresolved}, "other": {...}}``: verdict counts of the spec rows and of the
    other rows with a target (paper comparisons and our own checks)."""
    out = {"spec": dict.fromkeys(VERDICTS, 0), "other": dict.fromkeys(VERDICTS, 0)}
    for t in tables:
        for r in t["rows"]:
            if r.get("verdict") is not None:
                out["spec" if r.get("spec") else "other"][r["verdict"]] += 1
    return out
