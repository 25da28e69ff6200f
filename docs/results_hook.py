"""mkdocs hook (``hooks:`` in mkdocs.yml): the figures a page quotes, read from the results
files it cites, so that a figure cannot drift from its measurement.

A page writes a marker where the figure goes::

    {{ result("pst", "arrest_position_m", case="pst_elastic", lateral="free", digits=1) }}

and the build puts there the field ``arrest_position_m`` of the one row of
``results/pst.jsonl`` whose fields equal the other keywords (here ``case`` and
``lateral``). Options, not row filters: ``digits`` (decimals), ``scale`` (a factor, 100
for a percentage; a product or quotient of numbers such as ``1/1024`` for MiB to GiB or
``1e-9`` for G/s), ``sign`` (a leading ``+`` on positive values), ``unit`` (text after a
number), ``none`` (the text for a null value, e.g. "runs through"). A field may be a path
into a row's lists and tables: ``"slab_fractures.0.x_m"``, or ``"dx0.04.L_ca_m"`` for a
key that holds a dot. An unknown file
or field, a filter that matches no row or several, or any ``{{`` left over stops the
build.

README.md is read without a build: there a figure is written out, followed by the same
call in an HTML comment, ``66.9<!-- result("pst", ...) -->`` (text with spaces in
backticks); tests/test_docs_results.py checks that each written figure equals what the
call gives.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
OPTIONS = ("digits", "scale", "sign", "unit", "none")
MARKER = re.compile(r"\{\{\s*(.*?)\s*\}\}")
# a figure written out in README.md (a word, or any text in backticks) and the call it
# must equal
README_MARKER = re.compile(r"(`[^`]*`|[^\s|/(`]+)<!--\s*(result\(.*?\))\s*-->")


class ResultError(ValueError):
    """A marker that does not resolve to exactly one value."""


_cache: dict[Path, tuple[float, list[dict]]] = {}


def rows(name: str) -> list[dict]:
    """The rows of ``results/<name>.jsonl`` (read again when the file changes)."""
    path = RESULTS / f"{name}.jsonl"
    if not path.is_file():
        raise ResultError(f"no results file results/{name}.jsonl")
    mtime = path.stat().st_mtime
    if path not in _cache or _cache[path][0] != mtime:
        with open(path, encoding="utf-8") as fh:
            _cache[path] = (mtime, [json.loads(line) for line in fh if line.strip()])
    return _cache[path][1]


def result(name: str, field: str, /, **keys: Any) -> str:
    """The formatted value of ``field`` in the one row of ``name`` matching ``keys``."""
    opts = {k: keys.pop(k) for k in OPTIONS if k in keys}
    found = [r for r in rows(name) if all(k in r and r[k] == v for k, v in keys.items())]
    where = f"results/{name}.jsonl {keys or ''}".rstrip()
    if len(found) != 1:
        raise ResultError(f"{where}: {len(found)} rows match, not one")
    value: Any = found[0]
    parts = field.split(".")
    while parts:
        part = parts.pop(0)
        if (
            isinstance(value, list)
            and re.fullmatch(r"-?\d+", part)
            and -len(value) <= int(part) < len(value)
        ):
            value = value[int(part)]
            continue
        # a key may hold dots itself ("dx0.04"): the longest key that the path spells
        spelt = [".".join([part, *parts[:n]]) for n in range(len(parts), -1, -1)]
        key = next((k for k in spelt if isinstance(value, dict) and k in value), None)
        if key is None:
            raise ResultError(f"{where}: the row has no field {field!r}")
        value = value[key]
        del parts[: key.count(".")]
    if value is None:
        if "none" not in opts:
            raise ResultError(f"{where}: {field} is null (give none=... for its text)")
        return str(opts["none"])
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return str(value)
    value = value * opts.get("scale", 1)
    text = f"{value:.{opts['digits']}f}" if "digits" in opts else str(value)
    return ("+" if opts.get("sign") and value > 0 else "") + text + opts.get("unit", "")


def _number(node: ast.expr) -> float:
    """A number written as a literal or as products and quotients of literals."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Mult, ast.Div)):
        left, right = _number(node.left), _number(node.right)
        return left * right if isinstance(node.op, ast.Mult) else left / right
    value = ast.literal_eval(node)
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise ValueError(f"not a number: {ast.unparse(node)}")
    return value


def evaluate(call: str) -> str:
    """The value of one marker's text, ``result("name", "field", key=value, ...)``."""
    try:
        node = ast.parse(call, mode="eval").body
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
            raise ResultError(f"not a call: {call}")
        if node.func.id != "result":
            raise ResultError(f"unknown marker {node.func.id!r} (only result(...)): {call}")
        args = [ast.literal_eval(a) for a in node.args]
        kwargs = {
            k.arg: _number(k.value) if k.arg == "scale" else ast.literal_eval(k.value)
            for k in node.keywords
        }
    except (SyntaxError, ValueError, ZeroDivisionError) as e:
        if isinstance(e, ResultError):
            raise
        raise ResultError(f"cannot read the marker {{{{ {call} }}}}: {e}") from None
    if len(args) != 2 or None in kwargs:
        raise ResultError(f"result(name, field, key=value, ...) takes two names: {call}")
    return result(*args, **kwargs)


def substitute(text: str) -> str:
    """``text`` with every marker replaced by its value."""
    out = MARKER.sub(lambda m: evaluate(m.group(1)), text)
    if "{{" in out:
        line = next(ln for ln in out.splitlines() if "{{" in ln)
        raise ResultError(f"a marker that does not close on its line: {line.strip()}")
    return out


def readme_mismatches(text: str) -> list[str]:
    """Figures written out in ``text`` that differ from the result they cite."""
    bad = []
    for m in README_MARKER.finditer(text):
        written, call = m.group(1).strip("`"), m.group(2)
        try:
            expected = evaluate(call)
        except ResultError as e:
            bad.append(f"{written}: {e}")
            continue
        if written != expected:
            bad.append(f"{written} is written, {call} gives {expected}")
    return bad


def on_page_markdown(markdown: str, page: Any, **kwargs: Any) -> str:
    from mkdocs.exceptions import PluginError

    try:
        return substitute(markdown)
    except ResultError as e:
        raise PluginError(f"{page.file.src_uri}: {e}") from None
