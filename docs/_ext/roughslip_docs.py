"""Sphinx extension of the roughslip docs: references generated from the code.

``.. roughslip-config::`` renders every section and key of the run configuration from the
schema in :mod:`roughslip.run.config` (type, default, rule, description), so the reference cannot
drift from what ``load_config`` accepts. At build start the error-against-run-time figure and
tables of ``roughslip verify --quick``, and the figures and console output of
``scripts/docs_figures.py``, are made into ``docs/_generated/``. Console blocks and tables too
wide for the text column get a class that ``_static/roughslip.css`` fits to it
(:func:`fit_wide_blocks`).
"""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys
import typing
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

GENERATED = Path(__file__).resolve().parents[1] / "_generated"


def _type_name(tp) -> str:
    origin = typing.get_origin(tp)
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    if origin is list:
        return f"list of {_type_name(args[0])}"
    if args and origin is not None:  # Optional[X]
        return _type_name(args[0])
    return {float: "number", int: "integer", bool: "boolean", str: "string"}.get(tp, str(tp))


def _rule(meta) -> str:
    if meta.get("choices"):
        return "one of " + ", ".join(f"``{c}``" for c in meta["choices"])
    check = meta.get("check")
    return getattr(check, "rule", "") if check is not None else ""


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        v = f.default
    elif f.default_factory is not dataclasses.MISSING:
        v = f.default_factory()
    else:
        return ""
    if v is None:
        return "(unset)"
    if isinstance(v, bool):
        return f"``{str(v).lower()}``"
    if isinstance(v, str):
        return f'``"{v}"``'
    return f"``{v!r}``"


#: a placeholder address (``tcp://host:port``), which docutils would make a link
_PLACEHOLDER_URI = re.compile(r"\b[a-z]+://host:port\b")
#: literals and roles already marked up, which :func:`typeset` leaves alone
_MARKED = re.compile(r"(``.*?``|:\w+:`[^`]*`)")


def _outside_markup(text: str, pattern: str, repl) -> str:
    """``re.sub`` of ``pattern`` in the parts of ``text`` that are not literals or roles."""
    parts = _MARKED.split(text)
    parts[::2] = [re.sub(pattern, repl, part) for part in parts[::2]]
    return "".join(parts)


def typeset(text: str, names: tuple[str, ...] = ()) -> str:
    """The plain text of the code (the terminal's, the run file's) as reStructuredText for
    the references: configuration keys, quoted values and the ``names`` (datasets) as
    literals, the symbols of the model (``D_z``, ``lam f_z``, ``G_xx``, ``10^4``, ``E*``) as
    maths, a placeholder address as a literal, not a link."""
    from roughslip.run import config as C

    sub = _outside_markup
    text = sub(text, _PLACEHOLDER_URI.pattern, r"``\g<0>``")
    maths = [
        (r"\b0 <= lam_dynamic <= lam\b", r"0 \\le \\lambda_d \\le \\lambda"),
        (r"\blam_dynamic f_z\b", r"\\lambda_d f_z"),
        (r"\blam f_z\b", r"\\lambda f_z"),
        (r"\blambda_d\b", r"\\lambda_d"),
        (r"\blambda\b", r"\\lambda"),
        (r"\bO\(n\^2\)", r"O(n^2)"),
        (r"\bu_z - overlap\b", r"u_z - \\text{overlap}"),
        (r"\b([Du]_[xz]) = (\d+)\b", r"\1 = \2"),
        (r"\b([DdFfGu])_([a-z]{1,2})\b", r"\1_{\2}"),
        (r"\b10\^(\d+)\b", r"10^{\1}"),
        (r"~1e-(\d+)\b", r"\\sim 10^{-\1}"),
        (r"\bE\*", r"E^*"),
    ]
    for pattern, tex in maths:
        text = sub(text, pattern, lambda m, tex=tex: f":math:`{m.expand(tex)}`")
    sections = "|".join(sorted(C.SECTIONS, key=len, reverse=True))
    text = sub(text, rf"\b(?:{sections})\.[A-Za-z_]+\b", r"``\g<0>``")
    text = sub(text, r"'([^'\s]*)'\|'([^'\s]*)'", r"'\1' or '\2'")
    text = sub(text, r"\b(\w+) = '([^']*)'", r'``\1 = "\2"``')
    text = sub(text, r"(?<!\w)'([^'\s]+)'(?!\w)", r'``"\1"``')
    text = sub(text, r"\biy \* nx \+ ix\b", r"``iy * nx + ix``")
    if names:
        text = sub(text, r"\b(?:" + "|".join(map(re.escape, names)) + r")\b", r"``\g<0>``")
    units = [(r"\bx length\^2\b", "× length²"), (r"\bx um\^2\b", "× µm²"),
             (r"\bMPa x\b", "MPa ×"), (r"\buN\b", "µN")]
    for pattern, plain in units:
        text = sub(text, pattern, plain)
    return text


def _names() -> tuple[str, ...]:
    """The names that :func:`typeset` sets as literals: the stored datasets and the
    configuration keys with an underscore (``friction_force``, ``slip_distance``)."""
    from roughslip.run import config as C
    from roughslip.run import schema as S

    keys = {f.name for cls in C.SECTIONS.values() for f in dataclasses.fields(cls)}
    return tuple(sorted({c.name for c in S.all_columns()} | keys | {"pull_curve"}
                        - {"E"}, key=len, reverse=True))


def _rule_text(rule: str) -> str:
    """A rule of :func:`_rule` with its inequalities as maths (``-1 < nu <= 0.5``)."""
    def tex(part: str) -> str:
        # the left operand: a number or a short symbol (``nu``, ``H``, ``y0``), not a word
        m = re.fullmatch(r"(.*?)((?:(?<!\S)-?[\d.]+ |(?<!\S)[A-Za-z]\w{0,2} )?[<>]=?.*)", part)
        if m is None or not re.fullmatch(r"[-\w. <>=]+", m.group(2)):
            return part
        expr = m.group(2).replace("<=", r"\le").replace(">=", r"\ge")
        expr = re.sub(r"\bnu\b", r"\\nu", re.sub(r"\btol\b", r"\\mathrm{tol}", expr))
        return f"{m.group(1)}:math:`{expr}`"
    if "``" in rule:
        return rule
    return ", ".join(tex(part) for part in rule.split(", "))


def config_reference() -> list[str]:
    """reStructuredText of every section and key."""
    from roughslip.run import config as C
    from roughslip.run import digest as D

    lines: list[str] = []
    names = tuple(n for n in _names() if "_" in n)
    for name, cls in C.SECTIONS.items():
        hints = typing.get_type_hints(cls)
        doc = typeset(_links((cls.__doc__ or "").strip().splitlines()[0]))
        title = f"[{name}]"
        lines += [f".. _config-{name}:", "", title, "-" * len(title), "", doc, "",
                  ".. list-table::", "   :header-rows: 1", "   :widths: 18 12 12 22 36", "",
                  "   * - key", "     - type", "     - default", "     - rule",
                  "     - meaning"]
        for f in dataclasses.fields(cls):
            meta = f.metadata
            text = typeset(_links(meta.get("doc", "")), names).replace("|", "\\|")
            if name in ("surface", "elastic_surface"):
                kinds = [k for k, (allowed, _) in C.SURFACE_KEYS.items() if f.name in allowed]
                if f.name != "kind" and kinds:
                    text += f" (kind {', '.join(kinds)})"
            kind = _type_name(hints[f.name])
            if meta.get("dimension"):  # roughslip.run.units
                kind += f", or a {meta['dimension']} with a unit"
            lines += [f"   * - ``{f.name}``", f"     - {kind}",
                      f"     - {_default(f)}", f"     - {_rule_text(_rule(meta))}",
                      f"     - {text}"]
        lines.append("")
    renamed = ", ".join(f"``{s}.{old}`` (now ``{new}``)" for (s, old), new in
                        D.RENAMED.items())
    retired = ", ".join(f"``{s}.{k}`` ({why})" for (s, k), (_, _, why) in D.RETIRED.items())
    lines += ["Keys read under a former name: " + renamed + ".", "",
              "Keys accepted but without effect (kept so that older configurations load): "
              + retired + ".", ""]
    return lines


def schema_reference() -> list[str]:
    """reStructuredText tables of the output schema (:mod:`roughslip.run.schema`)."""
    from roughslip.run import schema as S

    names = tuple(n for n in _names() if "_" in n)
    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 24 12 10 54", "",
             "   * - dataset", "     - stage", "     - kind", "     - meaning"]
    for name, text in {**S.AXES, **S.ROOT}.items():
        lines += [f"   * - ``/{name}``", "     - ", "     - axis",
                  f"     - {typeset(text, names)}"]
    for c in S.all_columns():
        lines += [f"   * - ``/{c.name}``", f"     - {c.stage}", f"     - {c.kind}",
                  f"     - {typeset(_links(c.description), names)}"]
    lines += ["", ".. list-table::", "   :header-rows: 1", "   :widths: 24 22 54", "",
              "   * - field", "     - shape", "     - meaning"]
    for f in S.FIELDS:
        shape = "``(ny, nx)``" + (", boolean" if f.boolean else "") if f.grid else "one per event"
        lines += [f"   * - ``{f.name}``", f"     - {shape}",
                  f"     - {typeset(f.description, names)}"]
    groups = "; ".join(f"``{g}`` stores {', '.join(f'``{x}``' for x in xs)}"
                       for g, xs in S.FIELD_GROUPS.items())
    return [*lines, "", f"In ``output.fields``, {groups}.", ""]

class ConfigReference(SphinxDirective):
    has_content = False

    def run(self) -> list[nodes.Node]:
        container = nodes.section()
        nested_parse_with_titles(self.state, StringList(config_reference(), "roughslip-config"),
                                 container)
        return container.children


class SchemaReference(SphinxDirective):
    has_content = False

    def run(self) -> list[nodes.Node]:
        container = nodes.section()
        nested_parse_with_titles(self.state, StringList(schema_reference(), "roughslip-schema"),
                                 container)
        return container.children


def make_verify_figure(app) -> None:
    """``roughslip verify --quick --json --plot``: the work-precision diagrams, the points as
    JSON, and the table of estimates against the truth that the methods page shows. A broken
    claim (exit status 1) fails the build."""
    import json
    import math

    from roughslip.analysis.verify import summarize_checks

    GENERATED.mkdir(exist_ok=True)
    out = subprocess.run([sys.executable, "-m", "roughslip", "verify", "--quick", "--quiet",
                          "--json", "--plot", str(GENERATED / "verify")],
                         capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"roughslip verify --quick failed: {out.stderr.strip()}")
    (GENERATED / "verify_quick.json").write_text(out.stdout)
    data = json.loads(out.stdout)

    def ratio(r):
        lo, hi = r["ratio_min"], r["ratio_max"]
        return "(no estimate)" if math.isnan(lo) else f"{lo:.2g} to {hi:.2g}"

    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 26 10 10 24 10 20", "",
             "   * - estimate", "     - kind", "     - scene", "     - methods",
             "     - claim holds", "     - estimate / true error"]
    for r in summarize_checks(data["checks"]):
        holds = "no claim" if r["kind"] == "indicator" else f"{r['hold']} of {r['checks']}"
        lines += [f"   * - {r['estimate']}", f"     - {r['kind']}", f"     - {r['scene']}",
                  f"     - {', '.join(r['methods'])}", f"     - {holds}",
                  f"     - {ratio(r)}"]
    (GENERATED / "verify_checks.rst").write_text("\n".join(lines) + "\n")


def make_docs_figures(app) -> None:
    """``python scripts/docs_figures.py``: the quickstart's console output, the plots of its
    run, the Hurst loop and the Hertz resolution study, into ``_generated/figures``."""
    script = Path(__file__).resolve().parents[2] / "scripts" / "docs_figures.py"
    out = subprocess.run([sys.executable, str(script), str(GENERATED / "figures")],
                         capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"scripts/docs_figures.py failed: {out.stderr.strip()}")


_PAGE_LABEL = re.compile(r"docs/([\w/]+)\.(?:rst|md)#([\w-]+)")
_PAGE = re.compile(r"docs/([\w/]+)\.(?:rst|md)\b")
_LITERATURE = re.compile(r"\[(\w+)\] §")


def _links(line: str) -> str:
    """A line of the code's text with its references to pages (``docs/page.rst#label``) and to
    the literature (``[Key] §``) as links."""
    line = _PAGE_LABEL.sub(lambda m: f":ref:`{m.group(2).replace('-', ' ')} <{m.group(2)}>`",
                           line)
    line = _PAGE.sub(lambda m: f":doc:`/{m.group(1)}`", line)
    return _LITERATURE.sub(lambda m: f":ref:`[{m.group(1)}] <ref-{m.group(1).lower()}>` §",
                           line)


def _lookup(path: str):
    """The object that the dotted ``path`` names (a module, or an attribute of one); None
    when there is none."""
    import importlib

    parts = path.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            return None
        return obj
    return None


def resolve_imported(app, env, node, contnode):
    """A Python reference to a name as a module imports it (``roughslip.load_config``,
    ``InputError`` in a module that imports it), resolved to where the object is documented:
    its own module's name for it, or any documented name of the same object."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    module, cls = node.get("py:module"), node.get("py:class")
    places = [target]
    if module and cls:
        places.append(f"{module}.{cls}.{target}")
    if module:
        places.append(f"{module}.{target}")
    domain = env.get_domain("py")
    for place in places:
        owner_name, _, attr = place.rpartition(".")
        owner = _lookup(owner_name) if owner_name else None
        if node["reftype"] in ("attr", "meth") and isinstance(owner, type) and (
                hasattr(owner, attr) or attr in getattr(owner, "__annotations__", {})
                or re.search(rf"^\s*{attr}\b", owner.__doc__ or "", re.M)):
            # an attribute that its class documents in its Attributes section (numpydoc
            # gives those no target of their own), or a method of a protocol: the link goes
            # to the class
            for name in (f"{owner.__module__}.{owner.__qualname__}", owner_name):
                if name in domain.objects:
                    return domain.resolve_xref(env, node["refdoc"], app.builder, "obj",
                                               name, node, contnode)
        obj = _lookup(place)
        if obj is None:
            continue
        names = []
        if isinstance(obj, type(sys)):
            names.append(obj.__name__)
        elif getattr(obj, "__module__", None) and getattr(obj, "__qualname__", None):
            names.append(f"{obj.__module__}.{obj.__qualname__}")
        last = target.rsplit(".", 1)[-1]
        names += [name for name in domain.objects
                  if name.rsplit(".", 1)[-1] == last and _lookup(name) is obj]
        for name in names:
            if name != target and (name in domain.objects or name in domain.modules):
                found = domain.resolve_xref(env, node["refdoc"], app.builder, "obj", name,
                                            node, contnode)
                if found is not None:
                    return found
    # a bare name that one documented object of its kind ends with (``couple`` in a module
    # that does not import it)
    kinds = domain.objtypes_for_role(node["reftype"]) or []
    names = [name for name, entry in domain.objects.items()
             if name.endswith("." + target) and entry.objtype in kinds]
    if len(names) == 1:
        return domain.resolve_xref(env, node["refdoc"], app.builder, "obj", names[0], node,
                                   contnode)
    return None


def link_references(app, what, name, obj, options, lines: list[str]) -> None:
    """Links in the rendered docstrings (:func:`_links`)."""
    for i, line in enumerate(lines):
        lines[i] = _links(line)


#: monospace columns that fit the text column at the theme's font size, inside a list too
COLUMNS = 86
#: the widest block whose font is shrunk to fit; wider ones wrap instead
WIDEST = 150
#: tables with this many columns or more get the smaller font of ``wide-table``
WIDE_TABLE = 9


def _tabular(line: str) -> bool:
    """Whether a line is a row of aligned columns (two spaces or more between its fields)."""
    return bool(re.search(r"\S {2,}\S", line.strip()))


def block_class(text: str, language: str = "default") -> list[str]:
    """The classes that fit a literal block of ``text`` to the column (``_static/roughslip.css``).

    A few long lines among many short ones (a comment above a table, a command before its
    output), lines longer than :data:`WIDEST`, which no font size would fit, and in console
    output and messages (:data:`REWRAP`) lines of text rather than of columns (a message, a
    command) wrap at the column's edge: ``wrap`` (:func:`rewrap` breaks those of console
    output and messages into lines of their own where it can). Any other block is a table of
    text, or code: ``wide-<n>`` shrinks its font until ``n`` columns fit (its longest line,
    rounded up to 5).
    """
    lines = text.splitlines() or [""]
    width = max(len(line) for line in lines)
    if width <= COLUMNS:
        return []
    long = [line for line in lines if len(line) > COLUMNS]
    prose = language in REWRAP and not any(_tabular(line) for line in long)
    if width > WIDEST or (len(lines) > 3 and len(long) <= len(lines) // 4) or prose:
        return ["wrap"]
    return [f"wide-{5 * math.ceil(width / 5)}"]


def _hang(line: str) -> int:
    """Where the continuation lines of a long ``line`` start: under its value when it is a
    ``key   value`` line (the first run of two spaces or more, in the first half of the
    column), else four columns in from the line's own indent."""
    indent = len(line) - len(line.lstrip())
    m = re.match(r"\s*\S.*?\S? {2,}(?=\S)", line)
    if m and m.end() <= COLUMNS // 2:
        return m.end()
    return indent + 4


def _split(units: list[str], first: str, rest: str, width: int, end: str = "") -> list[str]:
    """``units`` (words, or an option with its value) over lines of at most ``width``
    columns: the first line starts with ``first``, the others with ``rest``; every line but
    the last ends with ``end``."""
    lines, line = [], first
    for unit in units:
        if line not in (first, rest) and len(line) + 1 + len(unit) + len(end) > width:
            lines.append(line + end)
            line = rest
        line += ("" if line in (first, rest) else " ") + unit
    return [*lines, line]


def _options(words: list[str]) -> list[str]:
    """The words of a command grouped into what a line break must not split: each option
    with the values that follow it (``--set grid.n=64``)."""
    units: list[str] = []
    for word in words:
        if units and units[-1].startswith("-") and not word.startswith("-"):
            units[-1] += " " + word
        else:
            units.append(word)
    return units


def rewrap(text: str, width: int = COLUMNS) -> str | None:
    """``text`` with its lines longer than ``width`` broken at spaces, as a terminal of that
    width would show them but with hanging indents: a command (``$ ...``) goes on over lines
    ending with a backslash, broken before an option; a comment (``# ...``) over comment
    lines; a message or a ``key   value`` line under its start (:func:`_hang`), together
    with the lines that already continue it there. None when a word is too long for any
    line."""
    src = text.splitlines()
    out: list[str] = []
    i = 0
    while i < len(src):
        line = src[i]
        indent = line[:len(line) - len(line.lstrip())]
        body = line.strip()
        i += 1
        if body.startswith(("$ ", "#")):
            if len(line) <= width:
                out.append(line)
            elif body.startswith("$ "):
                out += _split(_options(body[2:].split()), indent + "$ ", indent + "    ",
                              width, " \\")
            else:
                out += _split(body.lstrip("# ").split(), indent + "# ", indent + "#   ",
                              width)
            continue
        # a paragraph: the line and those that continue it already, indented to its hang
        hang = _hang(line)
        group = [line]
        while i < len(src) and src[i].strip() and len(src[i]) - len(src[i].lstrip()) == hang:
            group.append(src[i])
            i += 1
        if max(map(len, group)) <= width:
            out += group
            continue
        words = [w for x in group for w in x[hang:].split()]
        out += _split(words, line[:hang], " " * hang, width)
    if any(len(x) > width for x in out):
        return None
    return "\n".join(out) + ("\n" if text.endswith("\n") else "")


#: the languages whose long lines :func:`rewrap` may break (console output and messages; not
#: code, whose lines would change meaning)
REWRAP = ("console", "text", "none", "default")


def fit_wide_blocks(app, doctree) -> None:
    """Classes on the literal blocks too wide for the text column (:func:`block_class`), with
    the long lines of console output and messages broken (:func:`rewrap`), and ``wide-table``
    on the tables of :data:`WIDE_TABLE` columns or more."""
    for node in doctree.findall(nodes.literal_block):
        text = node.astext()
        language = node.get("language", "default")
        classes = block_class(text, language)
        if classes == ["wrap"] and language in REWRAP:
            wrapped = rewrap(text)
            if wrapped is not None:
                node.rawsource = wrapped
                node.children = [nodes.Text(wrapped)]
                classes = []
        node["classes"].extend(c for c in classes if c not in node["classes"])
    for table in doctree.findall(nodes.table):
        groups = list(table.findall(nodes.tgroup))
        if groups and int(groups[0].get("cols", 0)) >= WIDE_TABLE:
            table["classes"].append("wide-table")


def literal_placeholders(app, ctx, lines: list[str]) -> None:
    """The command-line reference (sphinx-click): a placeholder address in an option's help
    as a literal, not a link."""
    for i, line in enumerate(lines):
        lines[i] = _outside_markup(line, _PLACEHOLDER_URI.pattern, r"``\g<0>``")


#: the symbols of the commands' descriptions, which the terminal shows as plain text
_CLI_MATHS = ((r"\by = c x\^alpha\b", r":math:`y = c\,x^\alpha`"),
              (r"\bF_n\(D_z\)", r":math:`F_n(D_z)`"))


def cli_maths(app, ctx, lines: list[str]) -> None:
    """The command-line reference (sphinx-click): the symbols of a command's description
    (``y = c x^alpha``, ``F_n(D_z)``) as maths."""
    for i, line in enumerate(lines):
        for pattern, tex in _CLI_MATHS:
            line = _outside_markup(line, pattern, lambda m, tex=tex: tex)  # as written
        lines[i] = line


def no_protocol_signature(app, what, name, obj, options, signature, return_annotation):
    """A protocol class has no constructor of its own: show no ``(*args, **kwargs)``."""
    if what == "class" and getattr(obj, "_is_protocol", False):
        return "", return_annotation
    return None


def setup(app):
    app.add_css_file("roughslip.css")
    app.connect("doctree-read", fit_wide_blocks)
    app.add_directive("roughslip-config", ConfigReference)
    app.add_directive("roughslip-schema", SchemaReference)
    app.connect("autodoc-process-docstring", link_references)
    app.connect("autodoc-process-signature", no_protocol_signature)
    app.connect("missing-reference", resolve_imported)
    app.connect("sphinx-click-process-options", literal_placeholders)
    app.connect("sphinx-click-process-description", cli_maths)
    app.connect("builder-inited", make_verify_figure)
    app.connect("builder-inited", make_docs_figures)
    # env_version: the stored doctrees carry the classes and the broken lines of
    # fit_wide_blocks; a change to what the extension puts into them raises it, so that every
    # page is read again
    return {"parallel_read_safe": True, "parallel_write_safe": True, "env_version": 4}
