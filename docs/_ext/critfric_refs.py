"""The manual's generated references: the case-file keys (from ``critfric.case.schema``) and
the commands (from the typer app), as Markdown, written at build time.

Each generator is a plain function that returns Markdown text, so that the tests call them
without Sphinx (``tests/test_docs.py``). As a Sphinx extension (``docs/conf.py``), this module
writes their text into ``docs/_generated/`` when the build starts (only when it changed, so
that incremental builds stay incremental); the pages ``reference/case-file.md`` and
``reference/cli.md`` include those files. There is no hand-kept copy of a key or an option:
a new key or option appears in the manual with the next build.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

GENERATED = Path(__file__).resolve().parents[1] / "_generated"
HELP_WIDTH = 78  # click's width on a terminal of 80 columns or more: `critfric X --help`

# ----------------------------------------------------------------------------- Markdown


def md_escape(text: str) -> str:
    """``text`` as literal Markdown inline text: every punctuation character that Markdown or
    MyST reads (emphasis, links, raw HTML, math, table cells) escaped, except inside
    `code spans`, which stay code."""
    parts = re.split(r"(`[^`]+`)", text)
    special = re.compile(r"([\\*_\[\]<>|${}~#!])")
    return "".join(p if p.startswith("`") and p.endswith("`") and len(p) > 1
                   else special.sub(r"\\\1", p) for p in parts)


def code(text: str) -> str:
    """``text`` as one Markdown code span (in a table cell: ``|`` escaped)."""
    ticks = "``" if "`" in text else "`"
    pad = " " if "`" in text else ""
    return f"{ticks}{pad}{text}{pad}{ticks}".replace("|", "\\|")


def table(head: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(cell.replace("\n", " ") for cell in row) + " |" for row in rows]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- case files

#: the TOML type of each check of :mod:`critfric.case.checks`, by the check's maker
CHECK_TYPES = {
    "number": "float", "integer": "integer", "choice": "string", "boolean": "boolean",
    "string": "string", "path": "string (a path)", "names": "string or array of strings",
    "points": "array of [x, y]", "nodes": "array of [x, y] or [x, y, z]",
    "triple": "array of 3 floats", "index_rows": "array of integer arrays",
    "edge_table": "table of integer arrays", "face_table": "table of integer arrays",
    "string_list": "array of strings", "gamma": "integer", "friction_range": "array of 2 floats",
    "interval": "array of 2 floats", "vector": "array of 2 floats", "table_of": "table",
    "displacement": "array", "point_forces": "array of tables",
    "reference": "float or array of floats", "contact_rules": "array of tables",
    "subtable": "table",
}

#: what each section is for (a test checks that every section of the schema has one)
SECTIONS = {
    "": "Top-level keys, before the first section.",
    "geometry": "The body. `shape` selects which of the other keys apply (table below).",
    "boundary": "Which edges (3D: faces) are the contact boundary Gamma_C and which are "
                "clamped; every other edge is traction free.",
    "material": "Isotropic linear elasticity (plane strain in 2D).",
    "mesh": "The finite element and the mesh that gmsh makes.",
    "solve": "The eigen stage: solver, backend, how many coefficients, slip signs and "
             "directions.",
    "load": "The load of the static problem (2.8): used by `critfric solutions`, "
            "`critfric verify`, `critfric path` and `[contact] source = \"coulomb\"`.",
    "contact": "The contact state of the eigenproblem (3.2): which contact nodes are free, "
               "stuck or slipping, and in which direction.",
    "stability": "`critfric stability`: the sliding state's vibrations followed along friction.",
    "path": "`critfric path`: the solution curves of the static problem along one parameter.",
    "output": "The result file.",
}


def check_type(check) -> str:
    """The TOML type a schema check accepts, named after the check's maker."""
    maker = check.__qualname__.split(".")[0]
    if maker not in CHECK_TYPES:
        raise KeyError(f"critfric_refs.CHECK_TYPES has no TOML type for the check {maker!r}: "
                       "add it")
    return CHECK_TYPES[maker]


def allowed(check) -> str:
    """What a check allows, in the words of its own error message (a NaN fails every check of
    the schema: each one asks for finite numbers, or for no number at all)."""
    from critfric.case.checks import Bad

    try:
        check(math.nan)
    except Bad as bad:
        return str(bad)
    return "any value"


def toml_value(value) -> str:
    """A default value as TOML (a cell of the table; ``tomllib`` reads it back)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no TOML form for {value!r}")


def default_cell(default) -> str:
    from critfric.case.checks import REQUIRED

    if default is REQUIRED:
        return "*required*"
    if default is None:
        return "*unset*"
    return code(toml_value(default))


def case_file_markdown() -> str:
    """The case-file keys: per section, every key with its TOML type, default, allowed values,
    meaning and the command-line option that overrides it."""
    from critfric.case import schema as s

    options = {dotted: "--" + name.replace("_", "-") for name, dotted in s.OVERRIDES.items()}
    options["output.file"] = "--output/-o"
    missing = set(s.SCHEMA) - set(SECTIONS)
    if missing:
        raise KeyError(f"critfric_refs.SECTIONS has no text for [{sorted(missing)[0]}]: add it")
    head = ["key", "type", "default", "allowed", "meaning", "option"]
    out = []
    for section, keys in [("", s.TOP_LEVEL)] + list(s.SCHEMA.items()):
        out.append(f"## {code(f'[{section}]') if section else 'Top level'}\n")
        out.append(SECTIONS[section] + "\n")
        rows = []
        for key, spec in keys.items():
            dotted = f"{section}.{key}" if section else key
            option = options.get(dotted)
            rows.append([code(key), md_escape(check_type(spec.check)), default_cell(spec.default),
                         md_escape(allowed(spec.check)), md_escape(spec.doc),
                         code(option) if option else ""])
        out.append(table(head, rows) + "\n")
        if section == "geometry":
            out.append("Which keys each `shape` takes (any other `[geometry]` key is an "
                       "error):\n")
            out.append(table(["shape", "keys"], [
                [code(shape), ", ".join(code(k) for k in sorted(keys))]
                for shape, keys in s.SHAPE_KEYS.items()]) + "\n")
    low, high = s.NUMBER_RANGE
    out.append("## Limits\n")
    out.append(f"A case file has at most {s.MAX_CASE_BYTES >> 20} MB (a larger mesh belongs in "
               f"a `.msh` file), tables and arrays nested at most {s.MAX_DEPTH} levels deep, "
               f"integers below 2^63 and nonzero numbers of magnitude in [{low:g}, {high:g}].\n")
    return "\n".join(out)


# ----------------------------------------------------------------------------- commands


def _contexts():
    """The typer app as a command group, its root context and each command's context (the
    classes of the group itself, whatever click typer builds on)."""
    import typer.main

    from critfric.cli.app import app

    group = typer.main.get_command(app)
    root = group.make_context("critfric", [], resilient_parsing=True,
                              terminal_width=HELP_WIDTH)
    commands = []
    for name in group.list_commands(root):
        command = group.get_command(root, name)
        if command is not None and not command.hidden:
            commands.append((name, command, command.make_context(
                name, [], parent=root, resilient_parsing=True, terminal_width=HELP_WIDTH)))
    return group, root, commands


def help_text(name: str | None = None) -> str:
    """The text of ``critfric --help`` (``name``: of ``critfric NAME --help``) on a terminal of
    80 columns or more."""
    group, root, commands = _contexts()
    if name is None:
        return group.get_help(root)
    for cmd_name, command, ctx in commands:
        if cmd_name == name:
            return command.get_help(ctx)
    raise KeyError(name)


def _split_default(text: str) -> tuple[str, str]:
    """(help without its ``[default: ...]``, the default) of a help record (brackets may nest:
    ``[default: the case's [solve] slip_angle]``)."""
    start = text.find("[default: ")
    if start < 0:
        return text, ""
    depth, i = 0, start
    for i in range(start, len(text)):
        depth += {"[": 1, "]": -1}.get(text[i], 0)
        if depth == 0:
            break
    default = text[start + len("[default: "):i]
    before, after = text[:start].rstrip(), text[i + 1:].strip()
    glue = "" if not after or after[0] in ".,;:" else " "
    return (before + glue + after).strip(), default


def _parameters(command, ctx) -> list[list[str]]:
    rows = []
    for param in command.get_params(ctx):
        record = param.get_help_record(ctx)
        if record is None or getattr(param, "hidden", False):
            continue
        names, text = record
        text, default = _split_default(text)
        if text.endswith("[required]"):
            text, default = text.removesuffix("[required]").rstrip(), "required"
        if not default and param.param_type_name == "option" and param.default is False:
            default = "off"
        rows.append([code(names), md_escape(default), md_escape(text)])
    return rows


def _usage(command, ctx) -> str:
    return " ".join(command.collect_usage_pieces(ctx))


def cli_markdown() -> str:
    """Every command of the ``critfric`` app: its usage, what it does, each argument and
    option with its default and help, its examples, and its exact ``--help`` text."""
    group, root, commands = _contexts()
    out = ["## `critfric`\n", "```text\nUsage: critfric [OPTIONS] COMMAND [ARGS]...\n```\n",
           md_escape(group.help or "") + "\n",
           table(["option", "default", "help"], _parameters(group, root)) + "\n",
           "Commands: " + ", ".join(f"[`{name}`](#critfric-{name})" for name, _, _ in commands)
           + ".\n"]
    for name, command, ctx in commands:
        out.append(f"(critfric-{name})=\n## `critfric {name}`\n")
        out.append(f"```text\nUsage: critfric {name} {_usage(command, ctx)}\n```\n")
        out.append(md_escape(" ".join((command.help or "").split())) + "\n")
        out.append(table(["argument or option", "default", "help"], _parameters(command, ctx))
                   + "\n")
        examples = [line.strip() for line in (command.epilog or "").splitlines()
                    if line.strip().startswith("critfric ")]
        if examples:
            out.append("Examples:\n\n```sh\n" + "\n".join(examples) + "\n```\n")
        out.append(f"`critfric {name} --help`:\n\n```text\n{command.get_help(ctx)}\n```\n")
    out.append("`critfric --help`:\n\n```text\n" + group.get_help(root) + "\n```\n")
    return "\n".join(out)


# ----------------------------------------------------------------------------- Sphinx

PAGES = {"case-file-keys.md": case_file_markdown, "cli-commands.md": cli_markdown}


def write_generated(directory: Path = GENERATED) -> list[Path]:
    """Write every generated page into ``directory``; a file whose text is unchanged is left
    alone (its time stamp too, so Sphinx does not read its pages again)."""
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, make in PAGES.items():
        path, text = directory / name, make()
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")
            written.append(path)
    return written


def _builder_inited(app) -> None:
    write_generated(Path(app.srcdir) / "_generated")


def setup(app):
    app.connect("builder-inited", _builder_inited)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
