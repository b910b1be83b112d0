"""Sphinx configuration: the user guide (``docs/*.md``) and the API reference (``docs/api/``).

Build it as CI does (warnings are errors, every cross-reference must resolve)::

    python -m sphinx -W --keep-going -n -b html docs docs/_build/html

The API reference is rendered from the numpydoc docstrings; nothing here repeats a list
that the package keeps: the package-level names come from ``crlbswarm/__init__.pyi`` (what
``lazy_loader`` reads), the documented modules are the pages ``docs/api/crlbswarm.*.rst``,
and their public names are the modules' ``__all__``.
"""

from __future__ import annotations

import ast
import collections
import importlib
import inspect
import re
import sys
import types
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from numpydoc.xref import DEFAULT_LINKS, QUALIFIED_NAME_RE
from sphinx import addnodes
from sphinx.transforms.post_transforms import SphinxPostTransform
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
sys.path.insert(0, str(SRC))  # document this tree's code, installed or not

import crlbswarm  # noqa: E402

project = "crlbswarm"
author = "crlbswarm developers"
copyright = "crlbswarm developers"
release = version = crlbswarm.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
]

root_doc = "contents"
exclude_patterns = ["_build"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
html_theme = "alabaster"
html_title = f"crlbswarm {release}"
html_theme_options = {"description": "CRLB-optimal UAV formations", "fixed_sidebar": True}

# -- the user guide (Markdown) ------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3


# -- the public API, derived from the package ---------------------------------------------
def _package_exports() -> dict[str, str]:
    """``{name: module}`` of the package-level names, read from the stub lazy_loader uses."""
    tree = ast.parse((SRC / "crlbswarm" / "__init__.pyi").read_text(encoding="utf-8"))
    return {
        alias.asname or alias.name: f"crlbswarm.{node.module}"
        for node in tree.body
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module
        for alias in node.names
    }


def _home(module: types.ModuleType, name: str) -> str:
    """Dotted name of the module that defines (and documents) ``module.name``."""
    owner = getattr(getattr(module, name), "__module__", None)
    if isinstance(owner, str) and owner.startswith("crlbswarm."):
        return owner
    return module.__name__


PACKAGE_EXPORTS = _package_exports()
API_MODULES = sorted(p.stem for p in (HERE / "api").glob("crlbswarm.*.rst"))
#: Every public name of a documented module -> its full documented name.
PUBLIC_NAMES: dict[str, str] = {}
for _modname in API_MODULES:
    _module = importlib.import_module(_modname)
    for _name in _module.__all__:
        PUBLIC_NAMES.setdefault(_name, f"{_home(_module, _name)}.{_name}")

# -- the API reference --------------------------------------------------------------------
# Types are in the numpydoc Parameters and Returns sections; signatures show names and
# defaults only (the pydantic models' annotations would print as their FieldInfo reprs).
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False  # autodoc's :members: documents them, once
numpydoc_xref_param_type = True
# Type words of crlbswarm's own public names link to their entries; every other word of a
# type ("ndarray, shape (..., M, 2)", "float, default 0.01") is plain text: numpydoc's
# default links go to the Python and NumPy docs through intersphinx, which has no network
# here, so they are mapped to themselves (with xref_ignore "all", that is no link).
numpydoc_xref_aliases = {
    **{word: word for word in DEFAULT_LINKS if QUALIFIED_NAME_RE.match(word)},
    **PUBLIC_NAMES,
}
numpydoc_xref_ignore = "all"

# Nitpicky mode: references to crlbswarm must resolve; there is no intersphinx (no network),
# so the names of Python's standard library, NumPy, Matplotlib, ... in roles cannot.
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|scipy|sp|matplotlib|networkx|nx|dask|distributed|pydantic)(\..*)?"),
    (r"py:.*", r"(pathlib|os|collections|argparse|typing)(\..*)?"),
]


_TUPLE_FIELD = type(collections.namedtuple("_Probe", "field").field)


def _skip_generated_members(app, what, name, obj, skip, options):
    """Leave out pydantic's ``model_*`` namespace (``model_config``, ...) and the field
    accessors of named tuples ("Alias for field number 0"): the Parameters sections of the
    classes document their fields."""
    if what in ("class", "exception") and (
        name.startswith("model_") or isinstance(obj, _TUPLE_FIELD)
    ):
        return True
    return None


def _resolve_package_names(app, env, node, contnode):
    """Resolve ``crlbswarm.NAME`` (and ``crlbswarm.NAME.attr``): the package's public names
    are documented once, in the module that defines them."""
    if node.get("refdomain") != "py":
        return None
    head, _, rest = node["reftarget"].removeprefix("crlbswarm.").partition(".")
    if not node["reftarget"].startswith("crlbswarm.") or head not in PACKAGE_EXPORTS:
        return None
    target = f"{PACKAGE_EXPORTS[head]}.{head}" + (f".{rest}" if rest else "")
    domain = env.domains["py"]
    return domain.resolve_xref(
        env, node["refdoc"], app.builder, node["reftype"], target, node, contnode
    )


def _check_every_public_name_documented(app, env):
    """Warn (an error under -W) about a public name that autodoc left out, e.g. a Numba
    ``@vectorize`` ufunc, which ``:members:`` skips: document it with an explicit directive."""
    documented = set(env.domains["py"].objects)
    for full in PUBLIC_NAMES.values():
        if full not in documented:
            logging.getLogger(__name__).warning(
                "public name %s is not documented in docs/api/", full
            )


class PackageNames(SphinxDirective):
    """Table of the package-level names (``crlbswarm.NAME``), each linked to its entry."""

    def run(self):
        table = nodes.table(classes=["colwidths-given"], width="100%")
        group = nodes.tgroup(cols=3)
        table += group
        group.extend(nodes.colspec(colwidth=width) for width in (32, 22, 46))
        head, body = nodes.thead(), nodes.tbody()
        group.extend((head, body))
        head += self._row(["Name", "Module", "Summary"], module=None)
        for name in sorted(PACKAGE_EXPORTS, key=str.lower):
            module = PACKAGE_EXPORTS[name]
            cells = [
                f":py:obj:`crlbswarm.{name} <{module}.{name}>`",
                f":py:mod:`{module}`",
                _summary(module, name),
            ]
            body += self._row(cells, module=module)
        return [table]

    def _row(self, cells: list[str], module: str | None) -> nodes.row:
        """One row; the summary's references are relative to the module it comes from."""
        row = nodes.row()
        context = self.env.ref_context
        saved = context.pop("py:module", None)
        if module:
            context["py:module"] = module
        try:
            for text in cells:
                entry = nodes.entry()
                source = StringList([text], source="<crlbswarm/__init__.pyi>")
                self.state.nested_parse(source, self.content_offset, entry)
                row += entry
        finally:
            context.pop("py:module", None)
            if saved:
                context["py:module"] = saved
        return row


def _summary(module_name: str, name: str) -> str:
    """First paragraph of an object's docstring, or its ``#:`` comment for a constant."""
    from sphinx.pycode import ModuleAnalyzer

    obj = getattr(importlib.import_module(module_name), name)
    doc = None
    if inspect.isclass(obj) or callable(obj):
        doc = inspect.getdoc(obj)
    if not doc:
        attr_docs = ModuleAnalyzer.for_module(module_name).find_attr_docs()
        doc = "\n".join(attr_docs.get(("", name), []))
    return " ".join(doc.strip().split("\n\n")[0].split())


def _github_slugs_of_math_headings(app, doctree):
    """Give the Markdown headings with maths also the anchor GitHub gives them.

    MyST leaves the maths out of a heading's slug (``8-the-scaling-factor-``), GitHub keeps
    its source (``8-the-scaling-factor-eta_k``), and the guide's links use GitHub's, so that
    they work on both.
    """
    slugs = app.env.metadata[app.env.docname].get("myst_slugs")
    if not slugs:
        return
    depth = app.config.myst_heading_anchors
    for section in doctree.findall(nodes.section):
        title = section.next_node(nodes.title)
        level, parent = 0, section
        while parent is not None:
            level += isinstance(parent, nodes.section)
            parent = parent.parent
        if level > depth or title is None or title.next_node(nodes.math) is None:
            continue
        slug = re.sub(r"[^\w\- ]", "", title.astext().lower()).replace(" ", "-")  # GitHub's
        if slug and slug not in slugs:
            slugs[slug] = (section.line, section["ids"][0], title.astext())


class LinksOutOfDocs(SphinxPostTransform):
    """A Markdown link to a page of the repository outside ``docs/`` (``../README.md``)
    works on GitHub but has no page in this site: keep its text, without the link. (MyST
    itself turns a link to another existing file, ``../src/crlbswarm/radar.py``, into a
    download, and warns about a link to a file that does not exist.)"""

    default_priority = 8  # before MyST resolves its links (9)

    def run(self, **kwargs):
        srcdir = Path(self.env.srcdir).resolve()
        for node in list(self.document.findall(addnodes.pending_xref)):
            # MyST names an existing Markdown file outside the source folder by its
            # absolute path (without suffix) as the target document.
            target = Path(node.get("reftarget", ""))
            if (
                node.get("reftype") == "myst"
                and node.get("refdomain") == "doc"
                and target.is_absolute()
                and not target.is_relative_to(srcdir)
            ):
                node.replace_self(node[0].deepcopy())


def setup(app):
    app.add_directive("crlbswarm-package-names", PackageNames)
    app.connect("autodoc-skip-member", _skip_generated_members)
    app.connect("missing-reference", _resolve_package_names)
    app.connect("doctree-read", _github_slugs_of_math_headings)
    app.add_post_transform(LinksOutOfDocs)
    app.connect("env-check-consistency", _check_every_public_name_documented)
