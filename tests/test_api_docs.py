"""Documentation checks: every public function documents every parameter; examples run.

Following python-control: a public function that leaves a parameter undocumented fails
here, and the ``Examples`` sections of the docstrings are executed as doctests.
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import re
from pathlib import Path

import pytest

import crlbswarm

ROOT = Path(__file__).resolve().parents[1]
MODULES = [
    "crlbswarm.errors",
    "crlbswarm.radar",
    "crlbswarm.geometry",
    "crlbswarm.fisher",
    "crlbswarm.design",
    "crlbswarm.constrained",
    "crlbswarm.multitarget",
    "crlbswarm.formations",
    "crlbswarm.experiments",
    "crlbswarm.plots",
    "crlbswarm.animation",
    "crlbswarm.output",
    "crlbswarm.graphs",
    "crlbswarm.obstacles",
    "crlbswarm.spatial",
    "crlbswarm.counter_rng",
    "crlbswarm.links",
    "crlbswarm.safety",
    "crlbswarm.planning",
    "crlbswarm.control",
    "crlbswarm.scenario",
    "crlbswarm.scenario_checks",
    "crlbswarm.mission_kernel",
    "crlbswarm.simulation",
    "crlbswarm.results",
    "crlbswarm.estimation",
    "crlbswarm.montecarlo",
    "crlbswarm.three_d",
    "crlbswarm.tracking",
    "crlbswarm.campaign",
    "crlbswarm.paper",
    "crlbswarm.replay",
    "crlbswarm.report",
    "crlbswarm.webpage",
    "crlbswarm.flynet",
    "crlbswarm.uav_node",
    "crlbswarm.fly",
]


def _public_callables():
    for modname in MODULES:
        module = importlib.import_module(modname)
        for name in module.__all__:
            obj = getattr(module, name)
            if inspect.isfunction(obj):
                yield f"{modname}.{name}", obj
            elif inspect.isclass(obj):
                yield f"{modname}.{name}", obj
                for meth_name, meth in vars(obj).items():
                    if meth_name.startswith("_"):
                        continue
                    if inspect.isfunction(meth):
                        yield f"{modname}.{name}.{meth_name}", meth
                    elif isinstance(meth, classmethod):
                        yield f"{modname}.{name}.{meth_name}", meth.__func__


def _documented_parameters(doc: str) -> set[str]:
    """Names listed in the numpydoc ``Parameters`` (or ``Attributes``) section."""
    names: set[str] = set()
    for section in ("Parameters", "Attributes"):
        match = re.search(
            rf"^\s*{section}\n\s*-+\n(.*?)(?:\n\s*\n\s*\w[\w ]*\n\s*-+\n|\Z)", doc, re.S | re.M
        )
        if match:
            for line in match.group(1).splitlines():
                m = re.match(r"^\s{0,8}(\w+)\s*:", line)
                if m:
                    names.add(m.group(1))
    return names


def test_every_module_has_all_and_a_docstring():
    for modname in [*MODULES, "crlbswarm.cli"]:
        module = importlib.import_module(modname)
        assert module.__doc__, modname
        assert hasattr(module, "__all__"), modname


def test_package_exports_resolve():
    for name in crlbswarm.__all__:
        assert hasattr(crlbswarm, name), name


@pytest.mark.parametrize(("qualname", "obj"), list(_public_callables()))
def test_public_parameters_documented(qualname, obj):
    doc = inspect.getdoc(obj)
    assert doc, f"{qualname} has no docstring"
    target = obj.__init__ if inspect.isclass(obj) else obj
    try:
        params = inspect.signature(target).parameters
    except (TypeError, ValueError):  # pragma: no cover - builtins
        return
    wanted = {
        p
        for p, spec in params.items()
        if p not in ("self", "cls") and spec.kind not in (spec.VAR_POSITIONAL, spec.VAR_KEYWORD)
    }
    if inspect.isclass(obj) and "__init__" not in vars(obj) and not hasattr(obj, "__wrapped__"):
        wanted = set()  # an inherited constructor is documented where it is defined
    wanted -= {"_snr_constant"}
    missing = wanted - _documented_parameters(doc)
    assert not missing, f"{qualname}: parameters not documented: {sorted(missing)}"


@pytest.mark.parametrize("modname", MODULES)
def test_docstring_examples(modname):
    module = importlib.import_module(modname)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_readme_test_command_is_what_ci_runs():
    """`.ci/run` must run exactly the README's test command."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    test_cmd = 'pip install ".[test]" && python -m pytest'
    main_cmd = "pip install . && crlbswarm figures --out figures"
    head = "\n".join(readme.splitlines()[:25])
    assert main_cmd in head
    assert test_cmd in head
    assert any(line.strip() == test_cmd for line in ci.splitlines())
