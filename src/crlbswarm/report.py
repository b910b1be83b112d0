"""The report of a campaign: one self-contained HTML page from its Parquet dataset.

:func:`report_html` reads the folder written by ``crlbswarm sweep`` (:mod:`crlbswarm.campaign`:
``spec.json``, ``spec.toml``, ``variants.parquet`` and the hive-partitioned ``runs/``) and
returns a page that works offline, opened from a file: the data are embedded as JSON and
drawn by JavaScript written for it (``web/report.js`` and ``web/report.css`` of the
package, inlined; no library, no network). The page shows, per variant, the outcome counts,
the distributions of the final CRLB / bound, the convergence time, the clearance and the
separation (box plots of every variant, histograms of the selected one), the sweep's
parameters, and tables sortable by any column: one row per variant and one row per run of
the selected variant. docs/report.md describes the page.

A value that does not exist for a run is null in the dataset (the convergence time of a
run that did not converge, the clearance without obstacles; NaN and infinities read from a
file are treated alike): the page shows it as a dash, sorts it last in either direction,
and leaves it out of the medians, box plots and histograms, saying how many runs have no
value. The convergence time is taken only from the runs whose outcome is ``converged``: a
run that collided (or timed out) after its CRLB settled has a time in the dataset, but none
in the page.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__, _validation as _v
from .errors import FieldError, one_line
from .output import check_output_file, write_text
from .results import CENTROID_TOL, CRLB_TOL, OUTCOMES, PROGRESS_TOL
from .webpage import check_page_path, html_page, json_script, package_text

__all__ = [
    "DISTRIBUTIONS",
    "MAX_RUN_ROWS",
    "OUTCOME_TEXT",
    "Distribution",
    "report_data",
    "report_html",
    "write_report",
]

#: Most runs whose rows are embedded in the page (all variants together); above it the page
#: has the per-variant summaries, box plots and histograms only (a row takes about 80 bytes
#: for the paper scenario).
MAX_RUN_ROWS = 100_000


@dataclass(frozen=True)
class Distribution:
    """A per-run metric whose distributions the report draws.

    Attributes
    ----------
    key : str
        Its column in the dataset.
    label : str
        Its name in the page.
    short : str
        Its name in a table header.
    unit : str
        Its unit ("" for a ratio).
    worst : str
        ``"max"`` or ``"min"``: the bad end of its distribution (the table of variants
        shows the median and this end).
    missing : str
        What a missing value means.
    log : bool
        Drawn on a log scale when its values are positive and span more than 30 times.
    digits : int
        Significant digits shown in the page (the final CRLB / bound of converged runs
        differs from 1 in the fifth).
    """

    key: str
    label: str
    short: str
    unit: str
    worst: str
    missing: str
    log: bool
    digits: int


#: The metrics whose distributions the page draws.
DISTRIBUTIONS = (
    Distribution("final_crlb_ratio", "final CRLB / bound", "CRLB/bound", "", "max",
                 "not finite", True, 6),
    Distribution("convergence_time_s", "convergence time of the converged runs", "conv. time",
                 "s", "max", "the run's outcome is not converged (it did not converge, or it "
                 "collided: a run that collided after its CRLB settled has no time here)",
                 False, 4),
    Distribution("min_clearance_m", "smallest clearance to an obstacle", "clearance", "m",
                 "min", "no obstacles", False, 4),
    Distribution("min_separation_m", "smallest separation between two UAVs", "separation",
                 "m", "min", "not finite", False, 4),
)  # fmt: skip

#: What the outcomes mean (``MissionResult.metrics["outcome"]``), for the page.
OUTCOME_TEXT = (
    "collision (a UAV inside an obstacle, or two UAVs closer than safety.min_separation, at "
    f"any step), else converged (the CRLB within {100 * CRLB_TOL:g} % of the bound and the "
    f"centroid within {CENTROID_TOL:g} m of its place, held until the end for at least "
    f"time.hold), else timeout (the distance to go still fell by more than {PROGRESS_TOL:g} "
    "m over the last time.stall seconds) or stuck (it did not)"
)

#: Bins of each histogram (the same edges for every variant).
HIST_BINS = 20

#: Significant digits of the per-run values embedded in the page.
RUN_DIGITS = 6

#: Largest ``spec.json`` or ``spec.toml`` read, bytes (a campaign's are a few kB).
_MAX_SPEC_BYTES = 10 * 2**20

_VARIANT_FOLDER = re.compile(r"variant=(\d+)")


# -- reading a campaign folder ----------------------------------------------------------------
def _campaign_folder(campaign_dir: str | os.PathLike[str]) -> Path:
    """The folder, checked to hold a campaign (``spec.json`` and ``variants.parquet``)."""
    folder = Path(campaign_dir)
    if not folder.exists():
        raise FieldError("campaign_dir", f"{str(folder)!r} does not exist")
    if not folder.is_dir():
        raise FieldError("campaign_dir", f"{str(folder)!r} is not a folder")
    missing = [n for n in ("spec.json", "variants.parquet") if not (folder / n).is_file()]
    if missing:
        raise FieldError(
            "campaign_dir",
            f"{str(folder)!r} is not a campaign folder (no {' or '.join(missing)}; give the "
            "--out folder of crlbswarm sweep)",
        )
    return folder


def _read_small_text(path: Path) -> str:
    """A text file of the campaign, refused when larger than a spec can be."""
    if path.stat().st_size > _MAX_SPEC_BYTES:
        raise FieldError("campaign_dir", f"{str(path)!r} is larger than "
                         f"{_MAX_SPEC_BYTES // 2**20} MiB: not a campaign's file")  # fmt: skip
    return path.read_text(encoding="utf-8", errors="replace")


def _read_spec(folder: Path) -> tuple[dict[str, Any], str]:
    """The campaign spec of ``spec.json`` (with the base scenario's name and description)
    and the text of ``spec.toml`` (empty if absent)."""
    path = folder / "spec.json"
    try:
        canonical = json.loads(_read_small_text(path))
        spec = canonical["spec"]
        base = canonical.get("base") or {}
        if not isinstance(spec, dict) or not isinstance(base, dict):
            raise TypeError("not a table")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        reason = getattr(exc, "strerror", None) or one_line(str(exc), 100)
        raise FieldError(
            "campaign_dir", f"{str(path)!r} is not the spec.json of a campaign ({reason})"
        ) from None
    spec = {**spec, "base_name": base.get("name"), "base_description": base.get("description")}
    toml = folder / "spec.toml"
    return spec, (_read_small_text(toml) if toml.is_file() else "")


def _read_parquet(path: Path, columns: list[str] | None = None) -> Any:
    """A Parquet file as an Arrow table; an unreadable one is a one-line error."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        return pq.ParquetFile(path).read(columns=columns)
    except (OSError, pa.ArrowException) as exc:
        raise FieldError(
            "campaign_dir", f"cannot read {str(path)!r}: {one_line(str(exc), 200)}"
        ) from None


def _json_value(value: Any) -> Any:
    """A field value as the page shows it: numbers and strings as they are (non-finite
    numbers as None), anything else (a list, a table, a boolean) as its JSON text."""
    if isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, int | float):
        return float(value) if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return json.dumps(value, sort_keys=True, default=str)


def _read_variants(folder: Path) -> tuple[list[int], list[str], dict[str, list[Any]]]:
    """The variant ids, the changed fields and each field's values (``variants.parquet``)."""
    table = _read_parquet(folder / "variants.parquet")
    if "variant" not in table.column_names:
        raise FieldError("campaign_dir", f"{str(folder / 'variants.parquet')!r} has no "
                         "'variant' column: not a campaign's variants table")  # fmt: skip
    ids = [int(v) for v in table.column("variant").to_pylist()]
    fields = [n for n in table.column_names if n != "variant"]
    values = {n: [_json_value(x) for x in table.column(n).to_pylist()] for n in fields}
    return ids, fields, values


def _variant_parts(folder: Path) -> dict[int, list[Path]]:
    """The finished task files of each variant (``runs/variant=<id>/*.parquet``; hidden
    temporaries of interrupted writes skipped)."""
    parts: dict[int, list[Path]] = {}
    runs = folder / "runs"
    if not runs.is_dir():
        return parts
    for sub in sorted(runs.iterdir()):
        match = _VARIANT_FOLDER.fullmatch(sub.name)
        if match and sub.is_dir():
            files = [p for p in sorted(sub.glob("*.parquet")) if not p.name.startswith((".", "_"))]
            parts.setdefault(int(match.group(1)), []).extend(files)
    return parts


def _variant_runs(files: list[Path], fields: list[str]) -> dict[str, np.ndarray]:
    """The runs of one variant, by column: ``seed``, ``outcome`` and every numeric metric
    (the changed fields, which repeat the variant's values, left out); non-finite and null
    numbers are NaN, sorted by seed."""
    import pyarrow as pa

    columns: dict[str, list[np.ndarray]] = {}
    for path in files:
        table = _read_parquet(path)
        for name in table.column_names:
            column = table.column(name)
            if name == "outcome":
                array = np.asarray(column.to_pylist(), dtype=object)
            elif name == "seed":
                array = np.asarray(column.to_numpy(zero_copy_only=False), dtype=np.int64)
            elif name in fields or not (
                pa.types.is_floating(column.type) or pa.types.is_integer(column.type)
            ):  # a changed field (the variant's value again), or not a number
                continue
            else:  # (a null becomes NaN)
                array = np.asarray(column.to_numpy(zero_copy_only=False), dtype=float)
            columns.setdefault(name, []).append(array)
    out = {n: np.concatenate(parts) for n, parts in columns.items()}
    lengths = {len(a) for a in out.values()}
    if len(lengths) > 1 or (out and ("seed" not in out or "outcome" not in out)):
        where = str(files[0].parent) if files else "?"
        raise FieldError("campaign_dir", f"the task files of {where!r} do not share the "
                         "columns of a campaign (seed, outcome and the metrics)")  # fmt: skip
    if not out:
        return {"seed": np.zeros(0, dtype=np.int64), "outcome": np.zeros(0, dtype=object)}
    if "convergence_time_s" in out:  # a time only for the runs whose outcome is converged
        converged = out["outcome"].astype(str) == "converged"
        out["convergence_time_s"] = np.where(converged, out["convergence_time_s"], np.nan)
    order = np.argsort(out["seed"], kind="stable")
    return {n: np.where(np.isfinite(a), a, np.nan)[order] if a.dtype.kind == "f" else a[order]
            for n, a in out.items()}  # fmt: skip


# -- statistics --------------------------------------------------------------------------------
def _stats(values: np.ndarray) -> dict[str, Any]:
    """Count of runs with a value and without, and the quartiles, extremes and mean of the
    values (None when no run has one). Quartiles interpolate linearly (NumPy's and pandas'
    default)."""
    finite = values[np.isfinite(values)]
    out: dict[str, Any] = {"n": int(finite.size), "missing": int(values.size - finite.size)}
    if finite.size:
        q1, median, q3 = np.percentile(finite, [25.0, 50.0, 75.0])
        out.update(min=float(finite.min()), q1=float(q1), median=float(median), q3=float(q3),
                   max=float(finite.max()), mean=float(finite.mean()))  # fmt: skip
    else:
        out.update(min=None, q1=None, median=None, q3=None, max=None, mean=None)
    return out


def _edges(values: list[np.ndarray], log: bool) -> tuple[np.ndarray, bool]:
    """Histogram edges shared by every variant (with ``log``, log-spaced when the values are
    positive and span more than 30 times), and whether they are log-spaced."""
    finite = [v[np.isfinite(v)] for v in values]
    finite = [v for v in finite if v.size]
    if not finite:
        return np.linspace(0.0, 1.0, HIST_BINS + 1), False
    lo = min(float(v.min()) for v in finite)
    hi = max(float(v.max()) for v in finite)
    if log and lo > 0.0 and hi / lo > 30.0:  # from the decade below (an axis tick at lo)
        return np.geomspace(10.0 ** math.floor(math.log10(lo)), hi, HIST_BINS + 1), True
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi)):  # one value: a bin around it
        pad = 0.05 * max(abs(lo), 1.0)
        lo, hi = lo - pad, hi + pad
    return np.linspace(lo, hi, HIST_BINS + 1), False


def _compact(values: np.ndarray, digits: int = RUN_DIGITS) -> list[float | None]:
    """Numbers rounded to ``digits`` significant digits for the page (None for NaN)."""
    return [float(f"{x:.{digits}g}") if math.isfinite(x) else None for x in values.tolist()]


def _metric_meta(name: str) -> dict[str, Any]:
    """The label and unit of a per-run metric column, from its name (``min_clearance_m``:
    "min clearance", "m")."""
    for d in DISTRIBUTIONS:
        if d.key == name:
            return {"key": name, "label": d.label, "unit": d.unit, "missing": d.missing,
                    "digits": d.digits}  # fmt: skip
    base, unit = name, ""
    for suffix, u in (("_m2", "m²"), ("_m", "m"), ("_s", "s")):
        if name.endswith(suffix):
            base, unit = name[: -len(suffix)], u
            break
    words = [{"crlb": "CRLB", "eta": "η", "rms": "RMS"}.get(w, w) for w in base.split("_")]
    return {"key": name, "label": " ".join(words), "unit": unit, "missing": "not finite",
            "digits": 4}  # fmt: skip


# -- the page's data ---------------------------------------------------------------------------
def _variant_summary(vid: int, runs: dict[str, np.ndarray], outcomes: list[str]) -> dict[str, Any]:
    """One variant's outcome counts and the statistics of its distribution metrics."""
    names, counts = np.unique(runs["outcome"].astype(str), return_counts=True)
    found = dict(zip(names.tolist(), counts.tolist(), strict=True))
    outcomes.extend(n for n in found if n not in outcomes)  # an outcome this code lacks
    nan = np.full(len(runs["seed"]), np.nan)
    stats = {d.key: _stats(runs.get(d.key, nan)) for d in DISTRIBUTIONS}
    return {"id": vid, "runs": len(runs["seed"]), "counts": found, "stats": stats}


def _run_rows(runs: dict[str, np.ndarray], outcomes: list[str]) -> dict[str, list[Any]]:
    """The per-run rows of a variant, by column: seeds, outcome indices into ``outcomes``,
    and each metric's values (compact; None where missing)."""
    index = {name: i for i, name in enumerate(outcomes)}
    return {
        # (a seed beyond 2**53 as text: JavaScript's numbers would round it)
        "seed": [s if abs(s) < 2**53 else str(s) for s in runs["seed"].tolist()],
        "outcome": [index[str(o)] for o in runs["outcome"].tolist()],
        **{m: _compact(a) for m, a in runs.items() if m not in ("seed", "outcome")},
    }


def _read_runs(
    folder: Path, ids: list[int], fields: list[str], limit: int
) -> tuple[list[dict[str, Any]], list[dict[str, np.ndarray]], list[str], list[str]]:
    """Read the runs one variant at a time: each variant's summary (with its compact rows
    while the campaign has at most ``limit`` runs so far, else None), the values of the
    distribution metrics of each variant (finite only), the metric columns found and the
    outcomes (:data:`~crlbswarm.results.OUTCOMES`, then any other found)."""
    parts = _variant_parts(folder)
    outcomes = list(OUTCOMES)
    variants: list[dict[str, Any]] = []
    samples: list[dict[str, np.ndarray]] = []
    metrics: list[str] = []
    total = 0
    for vid in ids:
        runs = _variant_runs(parts.get(vid, []), fields)
        metrics += [n for n in runs if n not in metrics and n not in ("seed", "outcome")]
        variant = _variant_summary(vid, runs, outcomes)
        total += variant["runs"]
        variant["rows"] = _run_rows(runs, outcomes) if total <= limit else None
        samples.append({d.key: runs[d.key][np.isfinite(runs[d.key])] if d.key in runs
                        else np.zeros(0) for d in DISTRIBUTIONS})  # fmt: skip
        variants.append(variant)
    return variants, samples, metrics, outcomes


def report_data(
    campaign_dir: str | os.PathLike[str], *, max_run_rows: int = MAX_RUN_ROWS
) -> dict[str, Any]:
    """Read a campaign folder into the data of its report page (JSON-ready).

    Parameters
    ----------
    campaign_dir : str or path-like
        The output folder of ``crlbswarm sweep`` (:func:`crlbswarm.run_campaign`); a
        campaign still running or interrupted is read as far as its finished tasks go.
    max_run_rows : int, default MAX_RUN_ROWS
        Embed the per-run rows when the campaign has at most this many runs (0: never).

    Returns
    -------
    dict
        ``spec`` (from ``spec.json``), ``spec_toml``, ``fields`` (the changed fields),
        ``outcomes`` (their order: :data:`crlbswarm.results.OUTCOMES`, then any other found),
        ``distributions`` (each of :data:`DISTRIBUTIONS` with its histogram ``edges`` and
        ``log``), ``metrics`` (every per-run metric column, with label and unit),
        ``variants`` (per variant: ``id``, ``params``, ``runs``, ``expected`` runs,
        ``counts`` by outcome, ``stats`` and ``hist`` per distribution metric, and ``rows``,
        its runs by column, or None above ``max_run_rows``), ``total_runs``,
        ``rows_included``, ``max_run_rows``, ``outcome_text`` (:data:`OUTCOME_TEXT`).

    Raises
    ------
    FieldError
        Naming ``campaign_dir``: a missing folder, one that holds no campaign, or an
        unreadable file in it.
    """
    limit = _v.count(max_run_rows, "max_run_rows", 0)
    folder = _campaign_folder(campaign_dir)
    spec, spec_toml = _read_spec(folder)
    ids, fields, values = _read_variants(folder)
    variants, samples, metrics, outcomes = _read_runs(folder, ids, fields, limit)
    seeds = spec.get("seeds")
    count = seeds.get("count") if isinstance(seeds, dict) else None
    expected = count if isinstance(count, int) else None
    total = sum(v["runs"] for v in variants)
    embed = total <= limit
    distributions = []
    for d in DISTRIBUTIONS:
        edges, log = _edges([sample[d.key] for sample in samples], d.log)
        distributions.append({**asdict(d), "edges": edges.tolist(), "log": log,
                              "present": d.key in metrics})  # fmt: skip
        for variant, sample in zip(variants, samples, strict=True):
            variant.setdefault("hist", {})[d.key] = np.histogram(sample[d.key], edges)[0].tolist()
    for i, variant in enumerate(variants):
        variant["params"] = {f: values[f][i] for f in fields}
        variant["expected"] = expected
        rows, n = variant["rows"], variant["runs"]
        # (a column that some variants lack is missing in their rows)
        keys = ("seed", "outcome", *metrics)
        variant["rows"] = {k: rows.get(k, [None] * n) for k in keys} if embed else None
    return {
        "title": f"Campaign report: {folder.resolve().name}", "folder": str(folder),
        "version": __version__, "spec": spec, "spec_toml": spec_toml, "fields": fields,
        "field_kinds": {f: _kind(values[f]) for f in fields}, "outcomes": outcomes,
        "distributions": distributions, "metrics": [_metric_meta(m) for m in metrics],
        "variants": variants, "total_runs": total, "rows_included": embed,
        "max_run_rows": limit, "outcome_text": OUTCOME_TEXT,
    }  # fmt: skip


def _kind(values: list[Any]) -> str:
    """``number`` if every value is a number (or missing), else ``text``: how the page
    sorts a column."""
    return "number" if all(v is None or isinstance(v, float) for v in values) else "text"


def report_html(campaign_dir: str | os.PathLike[str], *, max_run_rows: int = MAX_RUN_ROWS) -> str:
    """The report page of a campaign: one self-contained HTML document.

    Parameters
    ----------
    campaign_dir : str or path-like
        The output folder of ``crlbswarm sweep``.
    max_run_rows : int, default MAX_RUN_ROWS
        Embed the per-run rows when the campaign has at most this many runs (0: never).

    Returns
    -------
    str
        The page: its data (:func:`report_data`), script and style inline; it loads
        nothing from elsewhere and works offline, opened from a file.

    Raises
    ------
    FieldError
        Naming ``campaign_dir`` if the folder holds no readable campaign.
    """
    data = report_data(campaign_dir, max_run_rows=max_run_rows)
    body = (
        '<main id="report"><noscript>This report is drawn by JavaScript: open it in a web '
        "browser with JavaScript enabled.</noscript></main>"
    )
    script = f"<script>\n{package_text('report.js')}\n</script>"
    return html_page(
        data["title"], package_text("report.css"), body, [json_script(data, "crlb-data"), script]
    )


def write_report(
    campaign_dir: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    max_run_rows: int = MAX_RUN_ROWS,
    on_write: Callable[[Path], None] | None = None,
) -> Path:
    """Write the report page of a campaign to a file (atomically).

    Everything is checked, and the page built, before the file is written: on an error
    nothing is written.

    Parameters
    ----------
    campaign_dir : str or path-like
        The output folder of ``crlbswarm sweep``.
    out : str or path-like
        The HTML file to write (``.html`` or ``.htm``); its folder must exist.
    overwrite : bool, default False
        Replace ``out`` if it exists.
    max_run_rows : int, default MAX_RUN_ROWS
        Embed the per-run rows when the campaign has at most this many runs (0: never).
    on_write : callable, optional
        Called with the path once written.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    FieldError
        Naming ``campaign_dir`` (no readable campaign) or ``out`` (a suffix other than
        ``.html`` or ``.htm``, a folder, an existing file without ``overwrite``, a missing
        or unwritable folder).
    """
    dest = check_output_file(check_page_path(out, "out"), "out", overwrite=overwrite)
    page = report_html(campaign_dir, max_run_rows=max_run_rows)
    write_text(dest, page)
    if on_write is not None:
        on_write(dest)
    return dest
