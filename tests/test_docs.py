"""The documentation: every reference in the code resolves inside the project, and every
command the guide shows runs.

References in code, tests and scripts take three forms, all checked here:

* ``docs/<page>.rst#<label>`` (or a page alone): the page exists and defines ``.. _label:``;
* ``erratum T<n>``: the errata page defines ``.. _erratum-t<n>:``;
* ``[Key] §...``: a literature reference listed on the references page (``.. _ref-key:``).

Notes kept outside the repository are never cited. Commands in ``.. code-block:: console``
blocks of the guide (lines starting with ``$``) are run in a scratch folder with the shipped
configurations; ``sh`` and ``python`` blocks are illustrations (a cluster, a file path) and
are not run.
"""

from __future__ import annotations

import builtins
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SOURCES = [p for d in ("roughslip", "tests", "scripts") for p in (ROOT / d).rglob("*.py")]
PAGE_REF = re.compile(r"docs/([\w/]+\.(?:rst|md))(?:#([\w-]+))?")
ERRATUM = re.compile(r"errat(?:um|a) T(\d+)")
LITERATURE = re.compile(r"\[(\w+)\] §")
#: names of working notes kept outside the repository, which no file may cite (spelled here in
#: lower case, so that this file does not cite them either)
OUTSIDE_NOTES = ("model", "green", "design", "style")
OUTSIDE = re.compile(r"\b(?:" + "|".join(n.upper() for n in OUTSIDE_NOTES)
                     + r")\b(?:\.md| ?§|:)?|\.\./shared")


def _labels(page: Path) -> set[str]:
    return set(re.findall(r"\.\. _([\w-]+):", page.read_text()))


def _problems(line: str, counts: dict[str, int] | None = None) -> list[str]:
    """What is wrong with the references on one line of code (empty: nothing)."""
    errata = _labels(DOCS / "theory" / "errata.rst")
    refs = _labels(DOCS / "theory" / "references.rst")
    counts = {} if counts is None else counts
    out = []
    if OUTSIDE.search(line):
        out.append(f"cites notes outside the project: {line.strip()}")
    for page, label in PAGE_REF.findall(line):
        counts["page"] = counts.get("page", 0) + 1
        target = DOCS / page
        if not target.is_file():
            out.append(f"no page docs/{page}")
        elif label and label not in _labels(target):
            out.append(f"docs/{page} has no label {label!r}")
    for t in ERRATUM.findall(line):
        counts["erratum"] = counts.get("erratum", 0) + 1
        if f"erratum-t{t}" not in errata:
            out.append(f"no erratum T{t}")
    for key in LITERATURE.findall(line):
        counts["literature"] = counts.get("literature", 0) + 1
        if f"ref-{key.lower()}" not in refs:
            out.append(f"[{key}] is not on the references page")
    if "§" in line and not LITERATURE.search(line):
        out.append("a section sign without a literature key")
    return out


def test_every_reference_in_the_code_resolves():
    problems: list[str] = []
    counts: dict[str, int] = {}
    for src in SOURCES:
        if src == Path(__file__).resolve():
            continue
        for n, line in enumerate(src.read_text().splitlines(), 1):
            problems += [f"{src.relative_to(ROOT)}:{n}: {p}" for p in _problems(line, counts)]
    assert problems == []
    assert set(counts) == {"page", "erratum", "literature"}, counts  # every form was seen


def test_the_checker_catches_dangling_references():
    bad = ["see docs/theory/pull.rst#no-such-label", "see docs/theory/nope.rst",
           "erratum T99", "[Nobody1900] §3", "report §4.6",
           *(f"{n.upper()} §2" for n in OUTSIDE_NOTES), f"see {OUTSIDE_NOTES[2].upper()}",
           f"{OUTSIDE_NOTES[1].upper()}.md"]
    for line in bad:
        assert _problems(line), line
    assert _problems("docs/theory/pull.rst#break-law, erratum T17, [Report2003] §4.6") == []


def _console_commands() -> list[tuple[str, str]]:
    out = []
    for page in sorted((DOCS / "guide").glob("*.rst")):
        lines = page.read_text().splitlines()
        inside = False
        for line in lines:
            if line.startswith(".. code-block::"):
                inside = line.split("::", 1)[1].strip() == "console"
                continue
            if inside and line and not line.startswith(" "):
                inside = False
            if inside and line.strip().startswith("$ "):
                out.append((page.name, line.strip()[2:]))
    return out


def test_guide_commands_are_found():
    """The typed commands of the guide. The quickstart's commands (``show-config`` among
    them), ``topography --formats`` and the Hurst loop are shown with their output, made by
    running them at every docs build (scripts/docs_figures.py), so a failing one fails
    ``make docs``; the commands typed on the pages are run here."""
    pages = {p for p, _ in _console_commands()}
    assert {"topographies.rst", "resume.rst"} <= pages


def test_the_generated_guide_output_is_what_the_script_writes():
    """Every console output and figure the pages include from ``_generated/figures`` is one
    that scripts/docs_figures.py writes."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_figures",
                                                  ROOT / "scripts" / "docs_figures.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    cells = re.findall(r"^# %% (\w+)$", (DOCS / "guide" / "python_tutorial.py").read_text(),
                       flags=re.M)
    written = ({f"quickstart_{n}.txt" for n, _ in mod.QUICKSTART} | set(mod.FIGURES)
               | {"topography_scan.txt", "topography_scan.png", "topography_formats.txt"}
               | {"hurst_loop.txt", "hurst_fit.png", "hertz_resolution.png",
                  "hertz_resolution.txt", "weakening_resolution.png",
                  "weakening_resolution.txt", "index_pull.png", "coupled_events.png",
                  "coupled_events.txt", "coulomb_cone.png", "spence_sphere.png", "histories.png",
                  "histories_weakening.png",
                  "bench_scaling.png",
                  "hertz_exponents.png", "rough_exponents.png", "coupled_finite_size.png",
                  "indentation.png", "traction_direction.png", "weakening_rough.png",
                  "burst_exponents.png",
                  "python_friction_coefficient.png", "python_sample0_fz.png"}
               | {f"python_{c}.{ext}" for c in cells for ext in ("py", "txt")})
    used = set()
    for page in [*DOCS.rglob("*.rst"), *DOCS.glob("*.md")]:
        if "_build" in page.parts:
            continue
        used |= set(re.findall(r"_generated/figures/([\w.]+)", page.read_text()))
    assert used and used <= written, used - written
    assert {"demo_pull.png", "demo_maps.png", "fit_friction.png", "fit_area.png",
            "bursts.png", "hertz_resolution.png", "hurst_fit.png",
            "weakening_resolution.png", "topography_scan.png", "topography_scan.txt",
            "index_pull.png", "coupled_events.png", "histories.png", "bench_scaling.png",
            "python_friction_coefficient.png", "python_sweep.py"} <= used


@pytest.mark.slow
def test_every_command_in_the_guide_runs(tmp_path):
    pytest.importorskip("SurfaceTopography", reason="the topography extra is not installed")
    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    (tmp_path / "runs").mkdir()
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"
           f"{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg"}
    for page, cmd in _console_commands():
        r = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 0, f"{page}: {cmd}\n{r.stdout}\n{r.stderr}"


def test_licence_and_citation_agree_with_the_package():
    """The licence file, the package metadata and the citation record name the same licence,
    and the citation record has the package's version."""
    from roughslip import __version__

    licence = (ROOT / "LICENSE").read_text()
    assert licence.startswith("BSD 3-Clause License")
    assert 'license = "BSD-3-Clause"' in (ROOT / "pyproject.toml").read_text()
    cff = (ROOT / "CITATION.cff").read_text()
    assert re.search(r"^cff-version: 1\.2\.0$", cff, re.M)
    assert re.search(r"^license: BSD-3-Clause$", cff, re.M)
    assert re.search(rf"^version: {re.escape(__version__)}$", cff, re.M)


HTML = ROOT / "docs" / "_build" / "html"
_RAW_ROLE = re.compile(r":(?:math|ref|func|doc|class|meth|mod|data|attr|term|numref):`")
_RAW_PATH = re.compile(r"\bdocs/[\w/]+\.(?:rst|md)\b")
#: an inline literal that docutils did not recognise shows its double backquotes
_RAW_LITERAL = re.compile(r"``")
#: maths left as text: a $...$ that MyST did not typeset, or an ASCII formula such as
#: "nu = 0.3", "F_n ~ D_z^beta" or "n^3" in prose
_RAW_MATH = re.compile(r"\$[^$\s][^$]*\$|\b(?:nu|lam|lambda|alpha|beta|gamma|[DFf]_[a-z]+)\s*"
                       r"(?:=|<|>|~|->)\s|\w\^[\w(]")
#: the hand-written Markdown pages, whose formulas must be typeset
_MARKDOWN_PAGES = ("results.html", "stability.html", "benchmarks.html")


def _visible_text(page: Path, maths: bool = True) -> str:
    """The text a reader sees: no scripts, styles, code or markup (and, with ``maths``
    false, no typeset maths either)."""
    import html

    text = re.sub(r"<(script|style|pre|code)\b[^>]*>.*?</\1>", " ", page.read_text(),
                  flags=re.S)
    if not maths:
        text = re.sub(r'<(span|div) class="math[^"]*"[^>]*>.*?</\1>', " ", text, flags=re.S)
    return html.unescape(re.sub(r"<[^>]+>", " ", text))


@pytest.mark.skipif(not (HTML / "index.html").exists(),
                    reason="the documentation is not built (make test builds it first)")
def test_rendered_pages_show_no_raw_role_or_source_path():
    """What the reader sees has no unrendered role (``:math:`...```), no source path
    (``docs/page.rst#label``) where a link belongs, and no double backquotes of an inline
    literal that docutils did not recognise (one right after a tilde, say)."""
    bad = []
    for page in sorted(HTML.rglob("*.html")):
        if {"_sources", "_static", "_modules"} & set(page.relative_to(HTML).parts):
            continue
        text = _visible_text(page)
        for m in [*_RAW_ROLE.finditer(text), *_RAW_PATH.finditer(text),
                  *_RAW_LITERAL.finditer(text)]:
            bad.append(f"{page.relative_to(HTML)}: ...{text[max(0, m.start() - 40):m.end()]}")
    assert not bad, "\n".join(bad[:20])


def test_the_raw_text_check_catches_what_it_should(tmp_path):
    page = tmp_path / "p.html"
    page.write_text("<p>see (docs/theory/pull.rst#break-law) and ~:math:`x`, ~``N``</p>"
                    "<pre>docs/stability.md is fine in code, ``so are these``</pre>")
    text = _visible_text(page)
    assert _RAW_PATH.findall(text) == ["docs/theory/pull.rst"] and _RAW_ROLE.search(text)
    assert _RAW_LITERAL.findall(text) == ["``", "``"]


@pytest.mark.skipif(not (HTML / "index.html").exists(),
                    reason="the documentation is not built (make test builds it first)")
def test_markdown_pages_typeset_their_formulas():
    """The results, stability and benchmark pages write formulas as maths, not as ASCII
    (``nu = 0.3``, ``F_n ~ D_z^beta``) and not as an unprocessed ``$...$``."""
    bad = []
    for name in _MARKDOWN_PAGES:
        text = _visible_text(HTML / name, maths=False)
        for m in _RAW_MATH.finditer(text):
            bad.append(f"{name}: ...{text[max(0, m.start() - 40):m.end() + 10]!r}")
    assert not bad, "\n".join(bad[:20])


def test_the_raw_maths_check_catches_what_it_should(tmp_path):
    page = tmp_path / "p.html"
    page.write_text('<p>at nu = 0.3 with $\\alpha$, n^3 flops and '
                    '<span class="math notranslate">\\(\\nu = 0.3\\)</span></p>'
                    "<pre>lam = 0.2 in code is fine</pre>")
    found = [m.group(0) for m in _RAW_MATH.finditer(_visible_text(page, maths=False))]
    assert found == ["nu = ", "$\\alpha$", "n^3"]


#: cross-references that may stay unlinked, as in conf.py's ``nitpick_ignore_regex``: names of
#: outside packages and of the standard library (no inventories are loaded: the build is
#: offline), and private names; the built-in names (``str``, ``DeprecationWarning``), which
#: Sphinx does not report, are in :data:`_BUILTINS`
_UNLINKED_OK = re.compile(r"^~?(?:(?:numpy|scipy|pandas|xarray|h5py|matplotlib|click|"
                          r"collections|typing)\.|(?:.*\.)?_[A-Za-z]\w*$|(?:Any|Callable)$)")
_BUILTINS = frozenset(dir(builtins))


def _unlinked_references(page: Path) -> list[str]:
    """The cross-references of a rendered page (``<code class="xref ...">``) that are not
    inside a link: a role whose target Sphinx did not find."""
    from html.parser import HTMLParser

    class Parser(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.open: list[str] = []
            self.xref: tuple[bool, str] | None = None
            self.bad: list[str] = []

        def handle_starttag(self, tag, attrs):
            if tag == "code" and "xref" in (dict(attrs).get("class") or "").split():
                self.xref = ("a" in self.open, "")
            self.open.append(tag)

        def handle_endtag(self, tag):
            if tag == "code" and self.xref is not None:
                linked, text = self.xref
                name = text.removesuffix("()")
                if not linked and not (_UNLINKED_OK.match(name) or name in _BUILTINS):
                    self.bad.append(text)
                self.xref = None
            while self.open and self.open.pop() != tag:
                pass

        def handle_data(self, data):
            if self.xref is not None:
                self.xref = (self.xref[0], self.xref[1] + data)

    parser = Parser()
    parser.feed(page.read_text())
    return parser.bad


@pytest.mark.skipif(not (HTML / "index.html").exists(),
                    reason="the documentation is not built (make test builds it first)")
def test_every_cross_reference_of_the_pages_is_a_link():
    """Every role that names code (``:func:``, ``:class:``, ``:data:``, ...), on the pages
    and in the docstrings of the API reference, links to where it is documented. ``make docs``
    refuses an unresolved one (nitpicky, warnings are errors); this checks the built site."""
    conf = (DOCS / "conf.py").read_text()
    assert re.search(r"^nitpicky = True$", conf, re.M)
    bad = []
    for page in sorted(HTML.rglob("*.html")):
        if {"_sources", "_static", "_modules"} & set(page.relative_to(HTML).parts):
            continue
        bad += [f"{page.relative_to(HTML)}: {name}" for name in _unlinked_references(page)]
    assert not bad, "\n".join(bad[:20])


def test_the_unlinked_reference_check_catches_what_it_should(tmp_path):
    page = tmp_path / "p.html"
    page.write_text('<p><a href="api.html#x"><code class="xref py py-func docutils">'
                    '<span class="pre">roughslip.squeeze()</span></code></a> '
                    '<code class="xref py py-class docutils"><span class="pre">InputError'
                    '</span></code> <code class="xref py py-class docutils"><span class="pre">'
                    'numpy.ndarray</span></code> <code class="xref py py-data docutils">'
                    '<span class="pre">_BOOT</span></code> <code class="xref py py-exc '
                    'docutils"><span class="pre">DeprecationWarning</span></code></p>')
    assert _unlinked_references(page) == ["InputError"]
