"""Reproduction summaries: ``DIR/summary.json`` in the schema of ``CONVENTIONS.md``.

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
                  figures=["fig2_heading_error.png"], notes=["follows SPEC erratum E3"])
"""

from __future__ import annotations

import ast
import json
import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Target", "summary_row", "summary_table", "write_summary", "evaluate_target", "check_expression",
           "SummaryError"]


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


def summary_row(quantity: str, unit: str, ours, paper=None, target=None,
                values: Mapping[str, float] | None = None) -> dict:
    """One row ``{quantity, unit, paper, ours, target, holds}``; ``holds`` is the verdict of ``target``
    (None without a target). ``paper`` None = the seed prints no number."""
    o, p = _num(ours), _num(paper)
    holds = None
    text = None
    if target is not None:
        text = target.text if isinstance(target, Target) else str(target)
        holds = evaluate_target(target, o, p, values) if o is not None else False
    return {"quantity": str(quantity), "unit": str(unit), "paper": p, "ours": o, "target": text,
            "holds": holds}


def summary_table(name: str, caption: str, rows: list[dict]) -> dict:
    """``{name, caption, rows}``."""
    return {"name": str(name), "caption": str(caption), "rows": list(rows)}


_ROW_KEYS = ("quantity", "unit", "paper", "ours", "target", "holds")


def write_summary(out_dir, *, seed: str, title: str, runs: int, base_seed: int, tables: list[dict],
                  figures: list[str] = (), notes: list[str] = (), aidnav_version: str | None = None) -> Path:
    """Write ``out_dir/summary.json`` (schema of ``CONVENTIONS.md``) and return its path.

    Rows must come from :func:`summary_row` (``holds`` computed); a row whose ``holds`` disagrees with
    its target, or that lacks a key, raises :class:`SummaryError` and nothing is written.
    """
    if aidnav_version is None:
        from aidnav.experiments.store import package_version

        aidnav_version = package_version()
    out_tables = []
    for t in tables:
        for k in ("name", "caption", "rows"):
            if k not in t:
                raise SummaryError(f"table {t.get('name', '?')!r}: missing key {k!r}")
        rows = []
        for r in t["rows"]:
            missing = [k for k in _ROW_KEYS if k not in r]
            if missing:
                raise SummaryError(f"table {t['name']!r}, row {r.get('quantity', '?')!r}: missing {missing} "
                                   "(make rows with summary_row)")
            if r["target"] is None and r["holds"] is not None:
                raise SummaryError(f"table {t['name']!r}, row {r['quantity']!r}: holds without a target")
            if r["holds"] is not None and not isinstance(r["holds"], bool):
                raise SummaryError(f"table {t['name']!r}, row {r['quantity']!r}: holds must be computed")
            rows.append({k: r[k] for k in _ROW_KEYS})
        out_tables.append({"name": t["name"], "caption": t["caption"], "rows": rows})
    doc = {"seed": str(seed), "title": str(title), "aidnav_version": aidnav_version, "runs": int(runs),
           "base_seed": int(base_seed), "tables": out_tables, "figures": [str(f) for f in figures],
           "notes": [str(n) for n in notes]}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "summary.json"
    tmp = out / "summary.json.tmp"
    tmp.write_text(json.dumps(doc, indent=2, allow_nan=False))
    tmp.replace(path)
    return path
