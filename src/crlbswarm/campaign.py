"""Monte Carlo campaigns on Dask: scenario variants times seeds, resumable, as Parquet.

A campaign is a TOML spec (:class:`CampaignSpec`): a base scenario, a grid (or a seeded
random sample) of changes to its fields, and a range of seeds per variant. Its runs are
grouped into tasks of ``batch_size`` seeds of one variant, so that the vectorised simulator
does the work, and the tasks are executed by a Dask cluster: a local one started for the
campaign by default, or an existing scheduler.

Output, under the campaign folder:

* ``spec.toml``: the spec, as given, and ``spec.json``: its canonical form (a folder holding
  another campaign's results is refused);
* ``variants.parquet``: one row per variant, its id and the value of every changed field;
* ``runs/variant=<id>/part-<first seed>-<last seed>.parquet``: one file per finished task,
  one row per run: the variant id, the seed, the changed fields and the per-run metrics of
  :class:`crlbswarm.MissionResult`. Together they form a hive-partitioned Parquet dataset,
  readable by ``pandas.read_parquet(folder / "runs")`` or ``polars.read_parquet``.

Every file is written atomically (temporary name, then rename), and a task's file exists
only once the task has finished, so re-running the same command resumes: finished tasks are
skipped, and an interrupted campaign loses only the tasks in flight. A task whose worker dies
is rescheduled by Dask (up to ``distributed.scheduler.allowed-failures`` times, 3 by
default); a task that fails (for example a diverged run) stops the campaign with one line
naming the variant and the seeds, keeping every finished task. With ``trajectories = true``
each task's positions go to ``trajectories/variant=<id>/part-<first>-<last>.npz``.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field, model_validator

from . import __version__, _validation as _v
from ._config import ConfigModel, read_toml, read_toml_file, validate
from .errors import CampaignError, FieldError, ScenarioError
from .output import atomic_path, write_text
from .scenario import BUILTIN_SCENARIOS, Scenario, scenario_data

__all__ = ["CampaignError", "CampaignSpec", "plan_tasks", "run_campaign", "run_task"]


class SeedRange(ConfigModel):
    """Seeds ``start, start + 1, ..., start + count - 1`` for every variant."""

    start: Annotated[int, Field(ge=0)] = Field(0, description="first seed")
    count: Annotated[int, Field(ge=1)] = Field(description="number of seeds per variant")


class Distribution(ConfigModel):
    """A random field value: ``uniform = [low, high]`` or ``choice = [a, b, ...]``."""

    uniform: Annotated[list[float], Field(min_length=2, max_length=2)] | None = Field(
        None, description="[low, high]: drawn uniformly"
    )
    choice: Annotated[list[Any], Field(min_length=1)] | None = Field(
        None, description="values, one drawn with equal probabilities"
    )

    @model_validator(mode="after")
    def _one(self) -> Distribution:
        if (self.uniform is None) == (self.choice is None):
            raise ValueError("give exactly one of 'uniform' and 'choice'")
        return self


class RandomSample(ConfigModel):
    """``samples`` variants with each field drawn from its distribution (seeded)."""

    samples: Annotated[int, Field(ge=1)] = Field(description="number of variants")
    seed: Annotated[int, Field(ge=0)] = Field(0, description="seed of the draws")
    fields: dict[str, Distribution] = Field(
        description="dotted scenario field -> its distribution"
    )


class CampaignSpec(ConfigModel):
    """A campaign: base scenario, variants (grid or random) and seeds.

    Each field is declared once below; this docstring's Parameters section is generated
    from the declarations.
    """

    base: str = Field(description="built-in scenario name or path of a scenario TOML file")
    seeds: SeedRange = Field(description="seeds of every variant")
    grid: dict[str, Annotated[list[Any], Field(min_length=1)]] | None = Field(
        None,
        description="dotted scenario fields and their values; the variants are their "
        "cartesian product",
    )
    random: RandomSample | None = Field(
        None, description="instead of grid: a seeded random sample of variants"
    )
    batch_size: Annotated[int, Field(ge=1)] = Field(
        250, description="runs per task (one variant, consecutive seeds)"
    )
    trajectories: bool = Field(
        False, description="also save each task's trajectories (.npz beside its Parquet file)"
    )

    @model_validator(mode="after")
    def _variants(self) -> CampaignSpec:
        if self.grid is not None and self.random is not None:
            raise ValueError("give at most one of 'grid' and 'random'")
        return self

    @classmethod
    def from_toml(cls, text: str, source: str = "campaign") -> CampaignSpec:
        """Parse and validate a spec from TOML text (errors name the field in one line).

        Parameters
        ----------
        text : str
            TOML document.
        source : str, default "campaign"
            Name used in error messages.

        Returns
        -------
        CampaignSpec
            The validated spec.
        """
        return validate(cls, read_toml(text, source), source)

    @classmethod
    def from_file(cls, path: str | Path) -> tuple[CampaignSpec, str]:
        """Read a spec file; a relative ``base`` scenario path is read from the file's folder.

        Parameters
        ----------
        path : str or path-like
            The spec (TOML).

        Returns
        -------
        spec : CampaignSpec
            The validated spec.
        text : str
            The file's text (saved beside the results).

        Raises
        ------
        ConfigError
            If the file cannot be read or is not a valid spec (one line naming the file and
            the field).
        """
        text, _ = read_toml_file(path)
        spec = cls.from_toml(text, source=str(path))
        beside = Path(path).parent / spec.base
        if not Path(spec.base).is_absolute() and beside.is_file():
            spec = spec.model_copy(update={"base": str(beside)})
        return spec, text

    def base_dict(self) -> dict[str, Any]:
        """The base scenario as a dictionary (built-in, or read from its TOML file).

        Returns
        -------
        dict
            Scenario data, ready for :meth:`crlbswarm.Scenario.from_dict`.
        """
        if self.base not in BUILTIN_SCENARIOS and not Path(self.base).is_file():
            known = ", ".join(BUILTIN_SCENARIOS)
            raise FieldError(
                "base", f"{self.base!r} is neither a built-in scenario ({known}) nor a file"
            )
        try:
            return scenario_data(self.base)[1]
        except ScenarioError as exc:  # a file that cannot be read or parsed
            raise FieldError("base", str(exc)) from None

    def variants(self) -> list[dict[str, Any]]:
        """The changed fields of every variant, in a fixed order.

        Returns
        -------
        list of dict
            One mapping of dotted field to value per variant (one empty mapping if the
            spec has neither grid nor random sample).
        """
        if self.grid is not None:
            names = list(self.grid)
            combos = itertools.product(*self.grid.values())
            return [dict(zip(names, combo, strict=True)) for combo in combos]
        if self.random is not None:
            rng = np.random.default_rng(self.random.seed)
            out = []
            for _ in range(self.random.samples):
                row = {}
                for name, dist in self.random.fields.items():
                    if dist.uniform is not None:
                        low, high = dist.uniform
                        row[name] = float(rng.uniform(low, high))
                    elif dist.choice is not None:  # (exactly one of the two is set)
                        row[name] = dist.choice[int(rng.integers(len(dist.choice)))]
                out.append(row)
            return out
        return [{}]


def _apply(base: dict[str, Any], changes: dict[str, Any], table: str) -> dict[str, Any]:
    """``base`` with the dotted fields of ``changes`` set; ``table`` (``grid`` or
    ``random.fields``) names where the changes came from, for errors."""
    data = copy.deepcopy(base)
    for dotted, value in changes.items():
        node = data
        *parents, leaf = dotted.split(".")
        for key in parents:
            node = node.setdefault(key, {})
            if not isinstance(node, dict):
                raise FieldError(f"{table}.{dotted}", f"'{key}' is not a table of the scenario")
        node[leaf] = value
    return data


def plan_tasks(spec: CampaignSpec) -> tuple[list[dict[str, Any]], list[tuple[int, int, int]]]:
    """Validate every variant's scenario and split the runs into tasks.

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.

    Returns
    -------
    scenarios : list of dict
        The scenario data of each variant (validated).
    tasks : list of (variant, first seed, last seed)
        Consecutive seeds of one variant, at most ``batch_size`` per task.

    Raises
    ------
    ScenarioError
        If a variant is not a valid scenario (one line naming the variant and the field).
    """
    base = spec.base_dict()
    scenarios = []
    for i, changes in enumerate(spec.variants()):
        data = _apply(base, changes, "random.fields" if spec.random is not None else "grid")
        Scenario.from_dict(data, source=f"variant {i} ({_label(changes)})")
        scenarios.append(data)
    first, count = spec.seeds.start, spec.seeds.count
    tasks = [
        (v, s, min(s + spec.batch_size, first + count) - 1)
        for v in range(len(scenarios))
        for s in range(first, first + count, spec.batch_size)
    ]
    return scenarios, tasks


def _label(changes: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in changes.items()) or "base"


def run_task(
    scenario: dict[str, Any], variant: int, first: int, last: int, trajectories: bool
) -> dict[str, Any]:
    """Simulate one task (a variant's seeds ``first..last``) and return its metrics.

    Runs on a Dask worker; Numba uses one thread there, the workers provide the parallelism.

    Parameters
    ----------
    scenario : dict
        The variant's scenario data.
    variant : int
        Variant id.
    first : int
        First seed.
    last : int
        Last seed (inclusive).
    trajectories : bool
        Also return the positions (B, K+1, M, 2).

    Returns
    -------
    dict
        ``columns`` (metric name to 1-D array, with ``variant`` and ``seed``) and optionally
        ``positions``.
    """
    import numba

    numba.set_num_threads(1)
    from .simulation import simulate

    result = simulate(
        Scenario.from_dict(scenario),
        seeds=range(first, last + 1),
        keep_trajectories=trajectories,
    )
    columns = {"variant": np.full(result.n_runs, variant, dtype=np.int64)}
    columns.update({k: np.asarray(v) for k, v in result.metrics.items()})
    out: dict[str, Any] = {"columns": columns}
    if trajectories:
        out["positions"] = result.positions
    return out


def _part_path(out: Path, variant: int, first: int, last: int) -> Path:
    return out / "runs" / f"variant={variant:05d}" / f"part-{first:012d}-{last:012d}.parquet"


def _write_part(
    path: Path, columns: dict[str, np.ndarray], changes: dict[str, Any], schema: Any
) -> None:
    """One task's rows; a changed field gets the type of its ``variants.parquet`` column, so
    every part of the dataset agrees (a grid [2, 3.0] is double everywhere)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = len(columns["seed"])
    table = {name: values for name, values in columns.items() if name != "variant"}
    for field, value in changes.items():
        table[field] = pa.array([value] * n, type=schema.field(field).type)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        pq.write_table(pa.table(table), tmp)


def run_campaign(
    spec: CampaignSpec,
    out: str | Path,
    *,
    scheduler: str | None = None,
    n_workers: int | None = None,
    spec_text: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, int]:
    """Run (or resume) a campaign on Dask and write its Parquet dataset under ``out``.

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.
    out : str or path-like
        Output folder (created if missing).
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:port``); by default a local
        cluster is started on this machine and closed at the end.
    n_workers : int, optional
        Workers of the local cluster (default: one per core).
    spec_text : str, optional
        The spec's TOML text, saved as ``spec.toml``.
    progress : callable, optional
        Called with (finished tasks, total tasks) after each task.

    Returns
    -------
    dict
        ``variants``, ``tasks``, ``skipped`` (already finished) and ``ran`` task counts.
    """
    if n_workers is not None:
        _v.count(n_workers, "n_workers", 1)
    folder = Path(out)
    scenarios, tasks = plan_tasks(spec)  # validate everything before anything runs
    variants = spec.variants()
    schema, digest = _prepare_folder(spec, folder, variants, spec_text)
    todo = [t for t in tasks if not _part_path(folder, *t).exists()]

    def report(done: int) -> None:
        if progress is not None:
            progress(done, len(tasks))

    finished = len(tasks) - len(todo)
    report(finished)
    if todo:
        _run_tasks(spec, folder, scenarios, variants, todo, schema, digest, scheduler,
                   n_workers, report, finished)  # fmt: skip
    return {
        "variants": len(variants),
        "tasks": len(tasks),
        "skipped": len(tasks) - len(todo),
        "ran": len(todo),
    }


def _prepare_folder(
    spec: CampaignSpec, folder: Path, variants: list[dict[str, Any]], spec_text: str | None
) -> tuple[Any, str]:
    """Check that ``folder`` is new or holds this campaign, write its spec and variants
    table, remove stale temporaries; return the variants' Arrow schema and the spec digest."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows: dict[str, list[Any]] = {"variant": list(range(len(variants)))}
    for name in sorted({k for v in variants for k in v}):
        rows[name] = [v.get(name) for v in variants]
    try:
        table = pa.table(rows)
    except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
        raise FieldError("grid", f"the values of a field must share one type ({exc})") from None
    # Resuming is only meaningful into the same campaign: refuse a folder holding another
    # (the spec and the resolved base scenario, so an edited base file counts as different).
    canonical = json.dumps(
        {"spec": spec.model_dump(), "base": spec.base_dict(), "crlbswarm": __version__},
        sort_keys=True,
    )
    marker = folder / "spec.json"
    if marker.exists() and marker.read_text(encoding="utf-8") != canonical:
        raise FieldError(
            "out",
            f"{str(folder)!r} holds the results of a different campaign (its spec.json "
            "differs); use another folder",
        )
    folder.mkdir(parents=True, exist_ok=True)
    write_text(marker, canonical)
    if spec_text is not None:
        write_text(folder / "spec.toml", spec_text)
    with atomic_path(folder / "variants.parquet") as tmp:
        pq.write_table(table, tmp)
    # Temporaries of tasks interrupted while being written (hidden files, which Parquet
    # readers skip) are stale: remove them.
    for stale in [*folder.glob("runs/*/.part-*"), *folder.glob("trajectories/*/.part-*")]:
        stale.unlink(missing_ok=True)
    return table.schema, hashlib.sha256(canonical.encode()).hexdigest()[:16]


def _run_tasks(spec: CampaignSpec, folder: Path, scenarios: list[dict[str, Any]],
               variants: list[dict[str, Any]], todo: list[tuple[int, int, int]], schema: Any,
               digest: str, scheduler: str | None, n_workers: int | None,
               progress: Callable[[int], None], done: int) -> None:  # fmt: skip
    """Run the unfinished tasks on Dask and write each one's files as it finishes; report
    the count of finished tasks (``done`` before the first) to ``progress``."""
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=n_workers, threads_per_worker=1, processes=True,
            dashboard_address=":0",  # any free port: never clash with another cluster
            silence_logs=logging.CRITICAL,  # failures are reported once, by this process
        )  # fmt: skip
    try:
        with Client(scheduler or cluster) as client:
            # Deterministic failures are not retried (they would fail again); a task whose
            # worker dies is rescheduled by Dask (distributed.scheduler.allowed-failures).
            futures = {
                client.submit(
                    run_task, scenarios[v], v, a, b, spec.trajectories,
                    key=f"crlbswarm-{digest}-{v}-{a}-{b}", retries=0, pure=False,
                ): (v, a, b)
                for v, a, b in todo
            }  # fmt: skip
            for future in as_completed(futures):
                v, a, b = futures.pop(future)
                try:
                    result = future.result()
                except (ValueError, RuntimeError) as exc:
                    raise CampaignError(
                        f"variant {v} ({_label(variants[v])}), seeds {a}..{b}: {exc}"
                    ) from None
                except Exception as exc:  # e.g. distributed.KilledWorker
                    raise CampaignError(
                        f"variant {v}, seeds {a}..{b}: {type(exc).__name__}: {exc}"
                    ) from None
                future.release()  # do not keep finished results on the workers
                path = _part_path(folder, v, a, b)
                # The Parquet part is written last: its presence marks the task done.
                if spec.trajectories:
                    npz = folder / "trajectories" / path.parent.name / f"{path.stem}.npz"
                    npz.parent.mkdir(parents=True, exist_ok=True)
                    with atomic_path(npz) as tmp:
                        np.savez(tmp, positions=result["positions"])
                _write_part(path, result["columns"], variants[v], schema)
                del result
                done += 1
                progress(done)
    finally:
        if cluster is not None:
            cluster.close()
