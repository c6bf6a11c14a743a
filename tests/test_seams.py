"""Seams (issue 36, item 6): no module imports another module's ``_private`` names. A name with a leading
underscore is its module's own; a name another module needs is public (renamed, listed in ``__all__``
where the module has one). Checked on the source tree with ``ast`` (imports inside functions count)."""

from __future__ import annotations

import ast
from pathlib import Path

import aidnav

SRC = Path(aidnav.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _resolve(node: ast.ImportFrom, here: str, is_pkg: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = here.split(".")
    base = base if is_pkg else base[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def private_imports() -> list[str]:
    """``module: from other import _name`` for every import of a private name from another module."""
    out = []
    for path in sorted(SRC.rglob("*.py")):
        here = _module_name(path)
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.ImportFrom):
                continue
            src = _resolve(node, here, path.name == "__init__.py")
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__") and src != here:
                    out.append(f"{here}:{node.lineno}: from {src} import {a.name}")
    return out


def test_no_private_names_imported_across_modules():
    bad = private_imports()
    assert not bad, f"{len(bad)} imports of another module's private names:\n" + "\n".join(bad)
