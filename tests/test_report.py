"""The campaign report (``crlbswarm report``): a self-contained page checked in a real
headless Chromium against an independent reading of the Parquet dataset with pandas.

Two campaigns: a tiny real one (``run_campaign`` on a local cluster of one worker, missions
of a few seconds), and a larger synthetic one written by the campaign module's own writers
(``variants.parquet``, ``spec.json``, the per-task Parquet files with their null
convention) without simulating, with the same schema as the real one (checked here):
values chosen so that numeric and lexicographic orders differ, and missing values (NaN and
infinities, stored as null) in several columns.
"""

from __future__ import annotations

import io
import json
import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from browser import open_page
from crlbswarm import campaign as campaign_module
from crlbswarm.campaign import CampaignSpec, run_campaign
from crlbswarm.cli import main
from crlbswarm.report import report_data, report_html, write_report
from crlbswarm.results import OUTCOMES

REAL_SPEC = """
base = "paper"
batch_size = 3
[seeds]
start = 5
count = 3
[grid]
"time.duration" = [4.0, 6.0]
"time.hold" = [1.0]
"time.stall" = [2.0]
"""

SYNTHETIC_SPEC = """
base = "paper"
batch_size = 4
[seeds]
start = 0
count = 10
[grid]
"control.cruise_speed" = [2.0, 10.0, 100.0, 9.5]
"graph.kind" = ["ring", "complete"]
"""

#: The per-run columns of a campaign of the paper scenario (checked against the real one).
METRICS = ("final_crlb_ratio", "final_centroid_error_m", "final_eta", "min_eta",
           "convergence_time_s", "min_clearance_m", "min_separation_m", "max_cost",
           "final_cost")  # fmt: skip

DISTRIBUTION_KEYS = ("final_crlb_ratio", "convergence_time_s", "min_clearance_m",
                     "min_separation_m")  # fmt: skip


# -- the datasets ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def real_campaign(tmp_path_factory) -> Path:
    """A real campaign: ``run_campaign`` on a Dask scheduler with one worker thread in this
    process (started in a fraction of a second, unlike worker processes)."""
    from distributed import LocalCluster

    folder = tmp_path_factory.mktemp("real") / "campaign"
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://",
        host="127.0.0.1", dashboard_address=None, silence_logs=logging.CRITICAL,
    ) as cluster:  # fmt: skip
        spec = CampaignSpec.from_toml(REAL_SPEC)
        run_campaign(spec, folder, scheduler=cluster.scheduler_address, spec_text=REAL_SPEC)
    return folder


def _synthetic_columns(v: int, seeds: np.ndarray, rng: np.random.Generator) -> dict:
    """Metrics of made-up runs: every outcome, NaN convergence times where a run did not
    converge, infinite clearances (no obstacles) for some variants, a NaN separation."""
    n = seeds.size
    weights = np.array([1.0, 2.0 + v, 1.0, 0.5 if v % 3 else 0.0, 0.2, 0.0 if v % 2 else 0.1])
    outcome = rng.choice(np.array(OUTCOMES), size=n, p=weights / weights.sum())
    if v == 5:  # no run of this variant converges: its convergence statistics are missing
        outcome[outcome == "converged"] = "timeout"
    conv = np.where(outcome == "converged", rng.uniform(40.0, 140.0, n), np.nan)
    clearance = np.full(n, np.inf) if v % 2 else rng.uniform(-0.5, 12.0, n)
    separation = rng.uniform(0.1, 9.0, n)
    separation[0] = np.nan if v == 2 else separation[0]
    cols = {"seed": seeds.astype(np.int64), "outcome": outcome}
    values = {
        "final_crlb_ratio": np.exp(rng.uniform(0.0, 3.0 * (v % 4 + 1), n)),
        "convergence_time_s": conv,
        "min_clearance_m": clearance,
        "min_separation_m": separation,
    }
    for name in METRICS:
        cols[name] = values.get(name, rng.normal(size=n))
    return cols


@pytest.fixture(scope="module")
def synthetic_campaign(tmp_path_factory) -> Path:
    """A campaign folder of 8 variants written by the campaign module's writers; variant 7
    lacks its last task (an unfinished campaign)."""
    folder = tmp_path_factory.mktemp("synthetic")
    spec = CampaignSpec.from_toml(SYNTHETIC_SPEC)
    variants = spec.variants()
    table = campaign_module._variants_table(variants)
    campaign_module._prepare_folder(
        folder, campaign_module._canonical(spec), table, SYNTHETIC_SPEC
    )
    rng = np.random.default_rng(13)
    for v, changes in enumerate(variants):
        for first in range(0, 10, 4):
            if v == 7 and first == 8:
                continue
            last = min(first + 3, 9)
            columns = _synthetic_columns(v, np.arange(first, last + 1), rng)
            path = campaign_module._part_path(folder, v, first, last)
            campaign_module._write_part(path, columns, changes, table.schema)
    return folder


def load_runs(folder: Path) -> pd.DataFrame:
    """The runs of a campaign, read independently of crlbswarm.report."""
    df = pd.read_parquet(folder / "runs")
    df["variant"] = df["variant"].astype(int)
    return df


def expected_variants(folder: Path) -> pd.DataFrame:
    """Per variant: runs, outcome counts and the medians of the distribution metrics."""
    runs = load_runs(folder)
    ids = pq.read_table(folder / "variants.parquet").column("variant").to_pylist()
    groups = runs.groupby("variant")
    out = pd.DataFrame(index=pd.Index(ids, name="variant"))
    out["runs"] = groups.size().reindex(ids, fill_value=0)
    for outcome in OUTCOMES:
        out[outcome] = groups["outcome"].apply(lambda s, o=outcome: int((s == o).sum()))
    for key in DISTRIBUTION_KEYS:
        out[f"{key}:median"] = groups[key].median()  # pandas skips the nulls
        out[f"{key}:min"] = groups[key].min()
        out[f"{key}:max"] = groups[key].max()
    return out


def wait_ready(page) -> None:
    page.wait_for_function("window.crlbReport && window.crlbReport.ready === true")


def cell_number(text: str) -> float | None:
    return None if text == "\u2014" else float(text)


def dom_table(page, table_id: str) -> tuple[list[str], list[list[str]]]:
    """The header keys and the cell texts of a table, as shown."""
    keys = page.eval_on_selector_all(f"#{table_id} thead th", "ths => ths.map(t => t.dataset.key)")
    rows = page.eval_on_selector_all(
        f"#{table_id} tbody tr",
        "trs => trs.map(tr => Array.from(tr.cells, td => td.textContent.trim()))",
    )
    return keys, rows


def assert_not_blank(png: bytes) -> None:
    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(float)
    assert image.shape[0] > 400
    assert image.shape[1] > 800
    assert image.std() > 20.0  # not one flat colour
    colours = np.unique(image.reshape(-1, 3)[::7], axis=0)
    assert len(colours) > 50  # text, bars, boxes of several colours


def close(shown: float | None, value: float | None, rel: float) -> bool:
    if shown is None or value is None or (isinstance(value, float) and math.isnan(value)):
        return shown is None and (value is None or math.isnan(value))
    return math.isclose(shown, value, rel_tol=rel, abs_tol=1e-12)


# -- the synthetic dataset has the real schema -------------------------------------------------
def test_synthetic_dataset_has_the_schema_of_a_real_campaign(real_campaign, synthetic_campaign):
    def schema(folder: Path, fields: set[str]) -> list[tuple[str, str]]:
        part = next(folder.glob("runs/variant=00000/part-*.parquet"))
        return [(f.name, str(f.type)) for f in pq.read_schema(part) if f.name not in fields]

    real = schema(real_campaign, {"time.duration", "time.hold", "time.stall"})
    synthetic = schema(synthetic_campaign, {"control.cruise_speed", "graph.kind"})
    assert real == synthetic
    assert [name for name, _ in real] == ["seed", "outcome", *METRICS]


# -- the real campaign, through the command line ----------------------------------------------
def test_report_of_a_real_campaign_matches_the_dataset(real_campaign, tmp_path, capsys):
    out = tmp_path / "report.html"
    assert main(["report", str(real_campaign), "-o", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    expected = expected_variants(real_campaign)
    assert expected["runs"].tolist() == [3, 3]
    with open_page(out) as page:
        wait_ready(page)
        keys, rows = dom_table(page, "variants")
        assert len(rows) == len(expected) == 2
        raw = page.evaluate("crlbReport.tableRows()")
        for row, values in zip(rows, raw, strict=True):
            v = int(row[keys.index("variant")])
            want = expected.loc[v]
            assert int(row[keys.index("runs")]) == want["runs"]
            for outcome in OUTCOMES:
                assert int(row[keys.index(f"outcome:{outcome}")]) == want[outcome]
            for key in DISTRIBUTION_KEYS:
                i = keys.index(f"{key}:median")
                assert close(values[i], want[f"{key}:median"], 1e-12), key
                assert close(cell_number(row[i]), want[f"{key}:median"], 1e-3), key
            assert float(row[keys.index("param:time.duration")]) == {0: 4.0, 1: 6.0}[v]
        assert_not_blank(page.screenshot())
        assert page.console_errors == []
        assert page.external_requests == []


# -- the synthetic campaign, in one page ---------------------------------------------------
@pytest.fixture(scope="module")
def synthetic_page(synthetic_campaign, tmp_path_factory):
    out = tmp_path_factory.mktemp("page") / "report.html"
    write_report(synthetic_campaign, out)
    with open_page(out) as page:
        wait_ready(page)
        page.report_path = out
        yield page


def test_page_loads_offline_without_errors(synthetic_page, synthetic_campaign):
    page = synthetic_page
    assert page.console_errors == []
    assert page.external_requests == []
    assert page.title() == f"Campaign report: {synthetic_campaign.name}"
    html = page.report_path.read_text(encoding="utf-8")
    for forbidden in ("http://", "https://", '<link rel="stylesheet"', "<script src"):
        assert forbidden not in html.replace('"http://www.w3.org/2000/svg"', "")
    # the campaign is unfinished (variant 7 misses a task): the page says so
    assert page.is_visible("#incomplete")
    assert_not_blank(page.screenshot())


def test_table_has_one_row_per_variant_matching_pandas(synthetic_page, synthetic_campaign):
    page = synthetic_page
    page.evaluate("crlbReport.sortBy('variant', 'asc')")
    expected = expected_variants(synthetic_campaign)
    keys, rows = dom_table(page, "variants")
    raw = page.evaluate("crlbReport.tableRows()")
    assert [int(r[0]) for r in rows] == list(expected.index) == list(range(8))
    assert expected["runs"].tolist() == [10] * 7 + [8]
    for row, values in zip(rows, raw, strict=True):
        want = expected.loc[int(row[0])]
        assert int(row[keys.index("runs")]) == want["runs"]
        for key in DISTRIBUTION_KEYS:
            for stat in ("median", "min", "max"):
                if f"{key}:{stat}" in keys:
                    i = keys.index(f"{key}:{stat}")
                    assert close(values[i], want[f"{key}:{stat}"], 1e-12), (key, stat)
                    assert close(cell_number(row[i]), want[f"{key}:{stat}"], 1e-3), (key, stat)
    # Missing statistics: variant 5 never converges; odd variants have no clearance.
    i = keys.index("convergence_time_s:median")
    assert rows[5][i] == "\u2014"
    assert raw[5][i] is None
    j = keys.index("min_clearance_m:median")
    assert [r[j] == "\u2014" for r in rows] == [v % 2 == 1 for v in range(8)]


def test_outcome_counts_shown_match_the_dataset(synthetic_page, synthetic_campaign):
    page = synthetic_page
    runs = load_runs(synthetic_campaign)
    counts = runs.groupby(["variant", "outcome"]).size()
    page.evaluate("crlbReport.sortBy('variant', 'asc')")
    keys, rows = dom_table(page, "variants")
    for row in rows:
        v = int(row[0])
        for outcome in OUTCOMES:
            assert int(row[keys.index(f"outcome:{outcome}")]) == counts.get((v, outcome), 0)
    # The totals of the header, and the list of the selected variant.
    for outcome in OUTCOMES:
        card = page.text_content(f'[data-card="{outcome}"] .card-value')
        assert int(card) == int((runs["outcome"] == outcome).sum())
    page.click('#variants tbody tr[data-id="3"]')  # a click on a row selects its variant
    assert page.evaluate("crlbReport.selected()") == 3
    for outcome in OUTCOMES:
        text = page.text_content(f'#detail-outcomes [data-outcome="{outcome}"]')
        assert text == f"{outcome}: {counts.get((3, outcome), 0)}"
    # The runs table of the selected variant: one row per run, its outcomes and seeds.
    _, run_rows = dom_table(page, "runs")
    mine = runs[runs["variant"] == 3].sort_values("seed")
    assert [int(r[0]) for r in run_rows] == mine["seed"].tolist()
    assert [r[1] for r in run_rows] == mine["outcome"].tolist()


def _sorted_ok(values: list, descending: bool) -> bool:
    present = [v for v in values if v is not None]
    missing_last = values[len(present) :] == [None] * (len(values) - len(present))
    return missing_last and present == sorted(present, reverse=descending)


@pytest.mark.parametrize(
    "key",
    ["param:control.cruise_speed", "param:graph.kind", "runs", "outcome:converged",
     "convergence_time_s:median", "min_clearance_m:min", "final_crlb_ratio:max"],
)  # fmt: skip
def test_clicking_a_header_sorts_the_column_both_ways(synthetic_page, key):
    page = synthetic_page
    page.evaluate("crlbReport.sortBy('variant', 'asc')")  # a known start
    keys, _ = dom_table(page, "variants")
    i = keys.index(key)
    numeric = key != "param:graph.kind"
    header = page.locator(f'#variants th[data-key="{key}"]')
    for click, direction in ((1, "ascending"), (2, "descending"), (3, "ascending")):
        header.click()
        _, rows = dom_table(page, "variants")
        cells = [r[i] for r in rows]
        values = [cell_number(c) for c in cells] if numeric else cells
        assert _sorted_ok(values, descending=direction == "descending"), (click, cells)
        header = page.locator(f'#variants th[data-key="{key}"]')
        assert header.get_attribute("aria-sort") == direction
        arrow = "\u25b2" if direction == "ascending" else "\u25bc"
        assert header.locator(".sort-indicator").text_content().strip() == arrow
        others = page.eval_on_selector_all(
            "#variants th[aria-sort]:not([aria-sort='none'])", "ths => ths.length"
        )
        assert others == 1
        state = page.evaluate("crlbReport.sortState()")
        assert state == {"column": key, "dir": "asc" if direction == "ascending" else "desc"}
    if key == "param:control.cruise_speed":  # numeric, not lexicographic
        header.click()  # descending
        header.click()  # ascending
        _, rows = dom_table(page, "variants")
        shown = list(dict.fromkeys(r[i] for r in rows))
        assert [float(c) for c in shown] == [2.0, 9.5, 10.0, 100.0]
        assert shown != sorted(shown)  # the text order would be 10, 100, 2, 9.5
    # The charts follow the table's order.
    assert page.evaluate("crlbReport.chartOrder()") == [
        int(r[0]) for r in dom_table(page, "variants")[1]
    ]


def test_runs_table_sorts_with_missing_values_last(synthetic_page, synthetic_campaign):
    page = synthetic_page
    page.evaluate("crlbReport.select(0)")
    keys, _ = dom_table(page, "runs")
    i = keys.index("convergence_time_s")
    runs = load_runs(synthetic_campaign)
    mine = runs[runs["variant"] == 0]
    for direction in ("asc", "desc"):
        page.evaluate(f"crlbReport.sortRunsBy('convergence_time_s', '{direction}')")
        _, rows = dom_table(page, "runs")
        values = [cell_number(r[i]) for r in rows]
        assert _sorted_ok(values, descending=direction == "desc")
        assert values.count(None) == int(mine["convergence_time_s"].isna().sum()) > 0
        raw = [r[i] for r in page.evaluate("crlbReport.runRows()")]
        expected = sorted(mine["convergence_time_s"].dropna(), reverse=direction == "desc")
        np.testing.assert_allclose([x for x in raw if x is not None], expected, rtol=1e-5)


# -- the library ----------------------------------------------------------------------------------
def test_report_data_handles_missing_values_and_the_row_limit(synthetic_campaign):
    data = report_data(synthetic_campaign, max_run_rows=0)
    assert data["rows_included"] is False
    assert all(v["rows"] is None for v in data["variants"])
    assert data["total_runs"] == 78
    v1 = data["variants"][1]  # infinite clearances: null in the dataset, missing here
    assert v1["stats"]["min_clearance_m"] == {
        "n": 0, "missing": 10, "min": None, "q1": None, "median": None, "q3": None,
        "max": None, "mean": None,
    }  # fmt: skip
    assert sum(v1["hist"]["min_clearance_m"]) == 0
    for v in data["variants"]:  # the histograms count the runs with a value
        for key in DISTRIBUTION_KEYS:
            assert sum(v["hist"][key]) == v["stats"][key]["n"]
    full = report_data(synthetic_campaign)
    assert full["rows_included"] is True
    rows = full["variants"][2]["rows"]
    assert rows["min_separation_m"][0] is None  # NaN in the task's columns
    assert len(rows["seed"]) == 10
    # JSON without NaN, safe in a script element.
    page = report_html(synthetic_campaign)
    opening = '<script type="application/json" id="crlb-data">'
    start = page.index(opening) + len(opening)
    embedded = json.loads(page[start : page.index("</script>", start)])
    assert embedded["variants"][5]["stats"]["convergence_time_s"]["median"] is None


# -- command-line errors ------------------------------------------------------------------------
def _report_cli(capsys, *argv: str) -> tuple[int, str]:
    status = main(["report", *argv])
    return status, capsys.readouterr().err


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("missing", r"^crlbswarm: error: CAMPAIGN_DIR: '.*nowhere' does not exist$"),
        ("empty", r"^crlbswarm: error: CAMPAIGN_DIR: '.*empty' is not a campaign folder"),
        ("file", r"^crlbswarm: error: CAMPAIGN_DIR: '.*spec.json' is not a folder$"),
        ("exists", r"^crlbswarm: error: -o/--out: '.*old.html' already exists; .*--force"),
        ("corrupt", r"^crlbswarm: error: CAMPAIGN_DIR: cannot read '.*part-.*\.parquet'"),
        ("rows", r"^crlbswarm: error: --max-run-rows: must be at least 0, got -1$"),
    ],
)  # fmt: skip
def test_cli_errors_print_one_line_exit_2_and_write_nothing(
    case, message, tmp_path, capsys, synthetic_campaign
):
    import re
    import shutil

    campaign = tmp_path / "campaign"
    shutil.copytree(synthetic_campaign, campaign)
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("not a campaign")
    out = tmp_path / "new.html"
    old = tmp_path / "old.html"
    old.write_text("keep me")
    extra: list[str] = []
    target = campaign
    if case == "missing":
        target = tmp_path / "nowhere"
    elif case == "empty":
        target = tmp_path / "empty"
    elif case == "file":
        target = campaign / "spec.json"
    elif case == "exists":
        out = old
    elif case == "corrupt":
        next(campaign.glob("runs/variant=00002/part-*.parquet")).write_bytes(b"PAR1 broken")
    elif case == "rows":
        extra = ["--max-run-rows", "-1"]
    before = sorted(p.name for p in tmp_path.iterdir())
    status, err = _report_cli(capsys, str(target), "-o", str(out), *extra)
    assert status == 2
    assert len(err.strip().splitlines()) == 1, err
    assert re.match(message, err.strip()), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert old.read_text() == "keep me"


def test_cli_force_replaces_the_page(tmp_path, capsys, synthetic_campaign):
    out = tmp_path / "report.html"
    out.write_text("old")
    status, err = _report_cli(capsys, str(synthetic_campaign), "-o", str(out), "--force")
    assert (status, err) == (0, "")
    text = out.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert "crlbReport" in text
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]  # no temporary left
