"""The shape of the house (docs/architecture.md): light imports, no private names across
modules, short functions, every parameter declared once and every other view derived."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydantic import BaseModel

import crlbswarm
from crlbswarm import BUILTIN_SCENARIOS, ControlGains, EtaRule, Radar, load_scenario
from crlbswarm.cli import build_parser, main
from crlbswarm.graphs import GRAPH_KINDS
from crlbswarm.radar import radar_field_names, radar_parameters
from crlbswarm.scenario import GraphConfig, RadarConfig, Scenario, builtin_scenario_text

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "crlbswarm"
HEAVY = {"matplotlib", "dask", "distributed", "pyarrow", "pandas", "tqdm", "tomlkit"}


def heavy_modules_after(code: str) -> list[str]:
    """The heavy libraries loaded by ``code`` in a fresh interpreter."""
    probe = (
        f"{code}\nimport sys, json\n"
        "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120
    )
    return sorted(set(json.loads(out.stdout.strip().splitlines()[-1])) & HEAVY)


def test_import_loads_no_heavy_library():
    assert heavy_modules_after("import crlbswarm") == []


@pytest.mark.parametrize(
    "argv",
    [["--version"], ["--help"], ["design", "--help"], ["design", "--uavs", "2"],
     ["simulate", "nowhere.toml", "--out", "x"], ["design", "--uavs", "4", "--json"]],
)  # fmt: skip
def test_cli_help_version_and_input_errors_load_no_heavy_library(argv):
    code = (
        "import contextlib, io\nfrom crlbswarm.cli import main\nquiet = io.StringIO()\n"
        "with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):\n"
        "    try:\n"
        f"        main({argv!r})\n"
        "    except SystemExit:\n"
        "        pass"
    )
    assert heavy_modules_after(code) == []


def _modules() -> dict[str, ast.Module]:
    return {p.stem: ast.parse(p.read_text(encoding="utf-8")) for p in sorted(SRC.glob("*.py"))}


def test_no_private_name_crosses_a_module():
    """Private *modules* (``_validation``, ``_config``, ``_numba``) are the package's shared
    helpers; private *names* stay in the module that defines them."""
    crossings = []
    for name, tree in _modules().items():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level >= 1 and node.module:
                crossings += [
                    f"{name}: from .{node.module} import {a.name}"
                    for a in node.names
                    if a.name.startswith("_") and not a.name.startswith("__")
                ]
            if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
                if node.attr.startswith("__"):
                    continue
                if isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
                    continue
                crossings.append(f"{name}:{node.lineno}: {ast.unparse(node)}")
    assert crossings == []


def test_no_function_is_longer_than_80_lines_of_code():
    """Docstrings aside; a longer function must say why in a ``# long:`` comment."""
    long = []
    for name, tree in _modules().items():
        lines = (SRC / f"{name}.py").read_text(encoding="utf-8").splitlines()
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            first = node.body[0]
            has_doc = isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
            start = first.end_lineno + 1 if has_doc and len(node.body) > 1 else first.lineno
            if node.end_lineno - start + 1 > 80 and "# long:" not in lines[node.lineno - 1]:
                long.append(f"{name}.{node.name}")
    assert long == []


def test_package_exports_resolve_and_match_the_stub():
    stub = ast.parse((SRC / "__init__.pyi").read_text(encoding="utf-8"))
    names = sorted(a.name for n in stub.body if isinstance(n, ast.ImportFrom) for a in n.names)
    assert sorted(crlbswarm.__all__) == names
    for name in names:
        assert getattr(crlbswarm, name) is not None, name


def test_every_public_module_has_an_api_page():
    """docs/api has one page per public module (Sphinx's -n would not notice a missing one
    unless something links to it)."""
    pages = {p.stem for p in (ROOT / "docs" / "api").glob("crlbswarm.*.rst")}
    modules = {f"crlbswarm.{p.stem}" for p in SRC.glob("*.py") if not p.stem.startswith("_")}
    assert pages == modules


def test_version_is_written_once():
    """pyproject reads it from crlbswarm.__version__; the installed metadata agrees."""
    from importlib.metadata import version

    assert version("crlbswarm") == crlbswarm.__version__
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert 'dynamic = ["version"]' in pyproject
    assert crlbswarm.__version__ not in pyproject


# -- one declaration per parameter ---------------------------------------------------------
def test_radar_table_of_a_scenario_is_derived_from_the_radar_fields():
    fields = RadarConfig.model_fields
    assert tuple(fields) == radar_field_names()
    for p in radar_parameters():
        assert fields[p.name].default == p.default == getattr(Radar(), p.name)
        assert p.unit in (fields[p.name].description or "") or not p.unit
    assert RadarConfig().to_radar() == Radar()


def test_radar_docstring_and_from_db_are_derived_from_the_declarations():
    doc = Radar.__doc__ or ""
    db_doc = Radar.from_db.__doc__ or ""
    for p in radar_parameters():
        assert f"{p.name} : float or array_like, default {p.default:g}" in doc
        assert f"{p.name} : float or array_like, optional" in db_doc
        if p.db_unit:
            assert f"{p.db_name} : float or array_like, optional" in db_doc
            # The decibel form of the default is the default.
            db = 10 * np.log10(p.default) + (30 if p.db_unit == "dBm" else 0)
            assert Radar.from_db(**{p.db_name: db}) == Radar()


def test_every_radar_field_has_its_cli_options():
    parser = build_parser()
    design = parser._subparsers._group_actions[0].choices["design"]
    options = {s for a in design._actions for s in a.option_strings}
    for p in radar_parameters():
        assert f"--{p.name.replace('_', '-')}" in options
        if p.db_unit:
            assert f"--{p.db_name.replace('_', '-')}" in options


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--power", "0.3"], Radar(tx_power=0.3)),
        (["--tx-power-dbm", "30"], Radar(tx_power=1.0)),
        (["--noise-dbm", "-80", "--rcs", "2"], Radar(noise_power=1e-11, rcs=2.0)),
        (["--frequency", "2.4e9", "--kappa", "3"], Radar(carrier_frequency=2.4e9, kappa=3.0)),
        (["--processing-gain-db", "20"], Radar(processing_gain=100.0)),
    ],
)
def test_cli_radar_options_build_the_declared_radar(argv, expected, capsys):
    assert main(["design", "--json", *argv]) == 0
    report = json.loads(capsys.readouterr().out)
    got = Radar(**report["radar"])
    for name in radar_field_names():
        assert getattr(got, name) == pytest.approx(getattr(expected, name), rel=1e-12), name


def test_scenario_sections_are_the_gains_types():
    assert Scenario.model_fields["control"].annotation is ControlGains
    assert Scenario.model_fields["eta"].annotation is EtaRule
    sc = load_scenario("paper")
    assert sc.control.kernel_tuple()._fields == tuple(ControlGains.model_fields)
    rule = sc.eta.kernel_tuple(sc.control)
    assert rule._fields == tuple(EtaRule.model_fields)
    assert rule.margin == sc.control.safety_radius  # margin defaults to the safety radius


def test_graph_kinds_are_declared_once():
    literal = GraphConfig.model_fields["kind"].annotation
    assert set(literal.__args__) == set(GRAPH_KINDS)
    for kind, options in GRAPH_KINDS.items():
        for option in options:
            assert option in GraphConfig.model_fields, (kind, option)


def _doc_table(text: str, section: str) -> dict[str, list[str]]:
    """The rows of the table under the heading of ``[section]`` in docs/scenarios.md, by
    field name: the cells, stripped of backticks."""
    start = text.index(f"### `[{section}]`")
    end = text.find("\n#", start + 1)
    rows = {}
    for line in text[start : end if end > 0 else None].splitlines():
        cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
        if line.startswith("| `") and len(cells) > 1:
            rows[cells[0]] = cells[1:]
    return rows


def _shows(cells: list[str], default: object) -> bool:
    """Whether one of the cells states ``default``."""
    for cell in cells:
        if isinstance(default, bool):
            if cell.lower() == str(default).lower():
                return True
            continue
        if isinstance(default, str) and cell.strip('"') == default:
            return True
        try:
            if isinstance(default, int | float) and float(cell) == float(default):
                return True
        except ValueError:
            pass
        if isinstance(default, list) and cell.replace(" ", "") == str(default).replace(" ", ""):
            return True
    return False


@pytest.mark.parametrize(
    "section",
    ["uavs", "time", "radar", "control", "disturbance", "graph", "eta", "estimation",
     "target_motion", "safety", "guidance", "formation"],
)  # fmt: skip
def test_scenario_docs_list_every_field_with_its_default(section):
    """docs/scenarios.md has a row for each field of each table, stating its default."""
    from pydantic_core import PydanticUndefined

    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    rows = _doc_table(text, section)
    model = Scenario.model_fields[section].annotation
    for name, info in model.model_fields.items():
        assert name in rows, f"[{section}] {name} is not documented"
        default = info.default
        if default is None or default is PydanticUndefined:
            continue
        assert _shows(rows[name], default), f"[{section}] {name}: default {default!r} not shown"


def test_every_scenario_table_is_documented():
    """Each table of the scenario (each field whose type is a model) has its section."""
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    for name, info in Scenario.model_fields.items():
        if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel):
            assert f"### `[{name}]`" in text, name


@pytest.mark.parametrize(("name", "heading"), [("paper", "5.1"), ("moving_target", "5.3")])
def test_scenario_docs_print_the_builtin_files(name, heading):
    """The files printed in docs/scenarios.md are the shipped ones, character for character."""
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    start = text.index("```toml\n", text.index(f"### {heading} `{name}`")) + len("```toml\n")
    assert text[start : text.index("```\n", start)] == builtin_scenario_text(name)


# -- built-in scenarios as packaged TOML -----------------------------------------------------
@pytest.mark.parametrize("name", list(BUILTIN_SCENARIOS))
def test_builtin_scenario_files_are_complete_and_canonical(name):
    """Each shipped file lists every field (the canonical dump of its own scenario, plus
    full-line comments), so what ``crlbswarm scenario show`` prints is the file itself and
    shows every default."""
    text = builtin_scenario_text(name)
    lines = [x for x in text.splitlines() if not x.startswith("#")]  # full-line comments
    canonical = [x for x in load_scenario(name).to_toml().splitlines() if not x.startswith("#")]
    assert lines == canonical
    assert Scenario.from_toml(text) == load_scenario(name)


def test_scenario_show_prints_the_packaged_file(capsys):
    for name in BUILTIN_SCENARIOS:
        assert main(["scenario", "show", name]) == 0
        assert capsys.readouterr().out == builtin_scenario_text(name)


def test_builtin_data_is_a_fresh_copy_each_time():
    a = BUILTIN_SCENARIOS["paper"]
    a["altitude"] = -1.0
    assert BUILTIN_SCENARIOS["paper"]["altitude"] == 20.0
    assert len(BUILTIN_SCENARIOS) == len(list(BUILTIN_SCENARIOS)) >= 3


def _package_imports(tree: ast.Module) -> set[str]:
    """The package modules a module imports (imports for type checking only left out)."""
    typing_only = {
        id(n)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING"
        for n in ast.walk(node)
    }
    out = set()
    for node in ast.walk(tree):
        if id(node) in typing_only or not isinstance(node, ast.ImportFrom) or node.level != 1:
            continue
        if node.module:
            out.add(node.module.split(".")[0])
        else:
            out |= {a.name for a in node.names if a.name != "__version__"}
    return out


def test_modules_import_only_from_lower_floors():
    """The floors of docs/architecture.md: every module is listed, and imports only from
    modules on lower floors (so the table is the true map of the package)."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    floors = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0].isdigit():
            floors[cells[1].strip("`")] = int(cells[0])
    modules = _modules()
    assert set(floors) == set(modules) - {"__init__"}
    upward = [
        f"{name} (floor {floors[name]}) imports {dep} (floor {floors[dep]})"
        for name, tree in modules.items()
        if name != "__init__"
        for dep in _package_imports(tree)
        if floors[dep] >= floors[name]
    ]
    assert upward == []
