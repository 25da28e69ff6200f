"""mkdocs hooks (``hooks:`` in mkdocs.yml): pages generated from the code, and a docstring
check, so that the reference cannot drift from the code.

- ``api/cli.md``: every subcommand's ``--help`` from `damjax.cli.build_parser`;
- ``api/scenario-keys.md``: the scenario-file keys with their kind, valid range, default
  and description, from the declarations of `damjax.params` (read through
  `damjax.scenario.schema`) and the slope and ensemble tables;
- ``api/params.md``: the tables of every field (unit, valid and plausible range, kind,
  default, flag, meaning) replace its ``<!-- fields: CLASS -->`` markers;
- a public function or class (``damjax.__all__`` and the ``__all__`` of the public
  modules, their public methods included) without a docstring stops the build.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import io
import os
import re
import types
from contextlib import redirect_stdout
from typing import Any

# modules whose names are public besides damjax.__all__; a module without __all__ exposes
# the functions and classes it defines whose names do not start with "_"
PUBLIC_MODULES = (
    "damjax.ensemble",
    "damjax.calibrate",
    "damjax.export",
    "damjax.export.gis",
    "damjax.export.avaframe",
    "damjax.snow_profiles",
    "damjax.snow_cover",
    "damjax.distributed",
    "damjax.scenario",
)


# --------------------------------------------------------------------------- docstrings


def _public_names(mod: types.ModuleType) -> list[str]:
    names = getattr(mod, "__all__", None)
    if names is not None:
        return list(names)
    return [
        n
        for n, o in vars(mod).items()
        if not n.startswith("_")
        and (inspect.isfunction(o) or inspect.isclass(o))
        and getattr(o, "__module__", "") == mod.__name__
    ]


def _member(mod: types.ModuleType, name: str) -> Any:
    if hasattr(mod, name):
        return getattr(mod, name)
    return importlib.import_module(f"{mod.__name__}.{name}")  # a submodule in __all__


def missing_docstrings() -> list[str]:
    """Public functions, classes, their public methods and modules without a docstring."""
    import damjax

    modules = [damjax] + [importlib.import_module(m) for m in PUBLIC_MODULES]
    modules += [o for o in (getattr(damjax, n) for n in damjax.__all__) if inspect.ismodule(o)]
    missing, seen = [], set()
    for mod in modules:
        if mod.__name__ in seen:
            continue
        seen.add(mod.__name__)
        if not (mod.__doc__ or "").strip():
            missing.append(f"module {mod.__name__}")
        for name in _public_names(mod):
            obj = _member(mod, name)
            where = f"{mod.__name__}.{name}"
            if inspect.ismodule(obj):
                if not (obj.__doc__ or "").strip():
                    missing.append(f"module {where}")
                continue
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue  # constants
            if not (obj.__doc__ or "").strip():
                missing.append(where)
            if inspect.isclass(obj):
                for k, v in vars(obj).items():
                    fn = v.fget if isinstance(v, property) else v
                    if k.startswith("_") or not (inspect.isfunction(fn)):
                        continue
                    if not (fn.__doc__ or "").strip():
                        missing.append(f"{where}.{k}")
    return sorted(set(missing))


def on_pre_build(config: Any) -> None:
    # mkdocs imported in the hooks only: tests/test_docs_api.py runs `missing_docstrings`
    # with the test extras, which do not install mkdocs
    from mkdocs.exceptions import PluginError

    missing = missing_docstrings()
    if missing:
        raise PluginError(
            f"{len(missing)} public name(s) without a docstring (docs/hooks.py): "
            + ", ".join(missing)
        )


# --------------------------------------------------------------------------- CLI


def cli_page() -> str:
    from damjax import cli

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "76"  # argparse wraps at the terminal width: fit the page
    try:
        parser = cli.build_parser()
        parser.prog = "damjax"
        sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
        out = [
            "# Command line",
            "",
            "Generated at build time from the argument parser (`damjax.cli.build_parser`), "
            "so it is what `damjax CMD --help` prints for the installed version.",
            "",
            "Exit status: 0 done, 2 bad input (one line per problem), 3 runtime fault "
            "(results written up to it), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM: "
            "`kill`, a scheduler's time limit); both write a checkpoint where the run "
            "takes them.",
            "",
            "```text",
            parser.format_help().rstrip(),
            "```",
            "",
        ]
        for name, p in sub.choices.items():
            p.prog = f"damjax {name}"
            out += [f"## `damjax {name}`", "", "```text", p.format_help().rstrip(), "```", ""]
        return "\n".join(out)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old


# --------------------------------------------------------------------------- scenario keys


def _cell(text: Any) -> str:
    return str(text).replace("|", "\\|").replace("[", "\\[").replace("\n", " ")


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        v = f.default
    elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        v = f.default_factory()  # type: ignore[misc]
    else:
        return "required"
    return f"`{v!r}`" if v is not None else "`None`"


def _dataclass_table(cls: type) -> list[str]:
    from damjax.params import specs
    from damjax.scenario import schema

    rows = ["| key | TOML value | default | meaning |", "|---|---|---|---|"]
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        valid = schema.valid_words(cls, f.name).removeprefix("must be ")
        spec = specs(cls)[f.name] if cls is not schema.Output else None
        if spec is not None and spec.kind == "choice":
            valid = "one of " + ", ".join(f'`"{c}"`' for c in spec.valid)
        elif spec is not None and isinstance(spec.valid, tuple) and spec.kind != "bool":
            # integer choices (dim): "{1, 2}" would be read as attributes by attr_list
            valid = "one of " + ", ".join(f"`{c}`" for c in spec.valid)
        doc = schema.key_doc(cls, f.name)
        rows.append(f"| `{f.name}` | {_cell(valid)} | {_default(f)} | {_cell(doc)} |")
    return rows


def fields_table(cls: type) -> str:
    """The declarations of a parameter or setup class (`damjax.params`) as a table."""
    from damjax.params import specs

    rows = [
        "| field | unit | valid | plausible | default | `damjax pst` | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    for f in dataclasses.fields(cls):
        spec = specs(cls)[f.name]
        valid = spec.valid_text.removesuffix(spec.unit).strip() if spec.valid is not None else ""
        plausible = f"{spec.plausible} ({spec.plausible_why})" if spec.plausible else ""
        meaning = spec.doc + (f"; None: {spec.optional}" if spec.optional else "")
        meaning += f". {spec.notes}" if spec.notes else ""
        flag = f"`{spec.flag}`" if spec.cli else ""
        cells = (spec.unit or "-", valid, plausible, _default(f), flag, meaning)
        rows.append(f"| `{f.name}` | " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(rows)


def _unit_table(table: dict[str, tuple[str, Any, str]]) -> list[str]:
    rows = ["| key | kind | valid | unit |", "|---|---|---|---|"]
    for key, (kind, check, unit) in table.items():
        if check is None:
            valid = ""
        elif isinstance(check, tuple) and len(check) == 2 and callable(check[0]):
            valid = check[1]
        else:
            valid = "one of " + ", ".join(f'`"{c}"`' for c in check)
        rows.append(f"| `{key}` | {kind} | {_cell(valid)} | {unit} |")
    return rows


def scenario_keys_page() -> str:
    from damjax import ensemble
    from damjax.params import PSTParams, PSTSetup, SlopeSetup
    from damjax.scenario import schema
    from damjax.scenario import slope as sslope

    out = [
        "# Scenario-file keys",
        "",
        "Generated at build time from the declarations of `damjax.params` (which the "
        "loader's checks read) and the tables of `damjax.scenario`, so every key, range "
        "and default here is the one the code accepts. SI units throughout, angles in "
        "degrees. A worked introduction is [Scenario files](../guide/scenarios.md).",
        "",
        "## Top level",
        "",
        "Tables and keys: " + ", ".join(f"`{k}`" for k in schema.TOP_KEYS) + ". `type` is "
        "one of " + ", ".join(f'`"{t}"`' for t in schema.SCENARIO_TYPES) + "; `name` "
        "matches `[A-Za-z0-9][A-Za-z0-9._-]*` and names the output folder.",
        "",
        "## `[params]` (`damjax.PSTParams`, PST and slope)",
        "",
        "On slopes, " + ", ".join(f"`{k}`" for k in sslope.PST_ONLY_PARAMS) + " have no "
        "meaning (the `[strength]` table sets the weak layer).",
        "",
        *_dataclass_table(PSTParams),
        "",
        '## `[setup]` of `type = "pst"` (`damjax.PSTSetup`)',
        "",
        *_dataclass_table(PSTSetup),
        "",
        '## `[setup]` of `type = "slope"` (`damjax.SlopeSetup`)',
        "",
        *_dataclass_table(SlopeSetup),
        "",
        "## `[output]`",
        "",
        *_dataclass_table(schema.Output),
        "",
        '## `[strength]` and `[profile]` of `type = "pst"`',
        "",
        "`[strength]` keys: " + ", ".join(f"`{k}`" for k in schema.STRENGTH_KEYS) + "; "
        "`[profile]` keys: " + ", ".join(f"`{k}`" for k in schema.PROFILE_KEYS) + ". Their "
        "meaning is in the format description of `damjax.scenario.schema` "
        "([API](scenario.md)).",
        "",
        '## `[terrain]` of `type = "slope"`',
        "",
        "`kind` is one of " + ", ".join(f'`"{k}"`' for k in sslope.TERRAIN_KINDS) + ".",
        "",
    ]
    for kind, table in sslope._TERRAIN_KEYS.items():
        out += [f'### `kind = "{kind}"`', "", *_unit_table(table), ""]
    out += [
        '## `[strength]` of `type = "slope"`',
        "",
        "`kind` is one of " + ", ".join(f'`"{k}"`' for k in sslope.STRENGTH_KINDS) + "; "
        "every kind also takes:",
        "",
        *_unit_table(sslope._STRENGTH_COMMON),
        "",
    ]
    for kind, table in sslope._STRENGTH_KEYS.items():
        out += [f'### `kind = "{kind}"`', "", *_unit_table(table), ""]
    out += [
        '## `[snow]` of `type = "slope"`',
        "",
        "`kind` is one of " + ", ".join(f'`"{k}"`' for k in sslope.SNOW_KINDS) + " "
        '(default `"uniform"`; sources and defaults: [the real-path guide]'
        "(../guide/real-path.md#snow-cover-and-weak-layer-on-terrain)); every kind also "
        "takes:",
        "",
        *_unit_table(sslope._SNOW_COMMON),
        "",
    ]
    for kind, table in sslope._SNOW_KEYS.items():
        if table:
            out += [f'### `kind = "{kind}"`', "", *_unit_table(table), ""]
    out += [
        "## `[ensemble]` (slope scenarios, `damjax ensemble`)",
        "",
        "Keys: " + ", ".join(f"`{k}`" for k in ensemble.ENSEMBLE_KEYS) + ". A drawn "
        "parameter `[ensemble.params.NAME]` (any scalar `[params]` field) or strength "
        "number `[ensemble.strength.NAME]` has `dist` = "
        + ", ".join(f'`"{d}"`' for d in ensemble.DISTRIBUTIONS)
        + " (normal, lognormal: `mean`, `std`; uniform: `low`, `high`; optional `bounds`). "
        "Strength numbers that can be drawn, per `[strength] kind`: "
        + "; ".join(
            f"{k}: " + (", ".join(f"`{n}`" for n in v) if v else "none")
            for k, v in ensemble.STRENGTH_DRAWS.items()
        )
        + ".",
        "",
    ]
    return "\n".join(out)


# --------------------------------------------------------------------------- files


GENERATED = {"api/cli.md": cli_page, "api/scenario-keys.md": scenario_keys_page}


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """``<!-- fields: CLASS -->`` (a class of `damjax.params`) -> its `fields_table`."""
    from damjax import params

    return re.sub(
        r"<!-- fields: (\w+) -->",
        lambda m: fields_table(getattr(params, m.group(1))),
        markdown,
    )


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    for uri, make in GENERATED.items():
        buf = io.StringIO()
        with redirect_stdout(buf):
            content = make()
        files.append(File.generated(config, uri, content=content))
    return files
