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
each task's whole result (trajectories and time series, the folder ``crlbswarm simulate``
writes) goes to ``trajectories/variant=<id>/part-<first>-<last>/``, which
:func:`crlbswarm.load_results` reads (one part, or the variant's folder with all its parts).

Safety (docs/campaigns.md): every size is checked before anything is allocated
(:data:`MAX_VARIANTS`, :data:`MAX_TASKS`, the memory of one task); the cluster is up (a local
one listening on 127.0.0.1 only, or a scheduler reached within ``connect_timeout``) before the
folder is created; the folder is locked (``.crlbswarm-sweep.lock``, ``flock``) while a
campaign writes to it, so two processes never share it.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import itertools
import json
import logging
import math
import os
import shutil
import socket
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Any
from urllib.parse import urlsplit

import numpy as np
from pydantic import Field, field_validator, model_validator

from . import __version__, _validation as _v
from ._config import ConfigModel, read_toml, read_toml_file, validate
from .errors import (
    CampaignError,
    FieldError,
    ScenarioError,
    SimulationDivergedError,
    one_line,
)
from .output import STAGE_PREFIX, atomic_path, check_output_folder, write_text
from .scenario import BUILTIN_SCENARIOS, Scenario, scenario_data

__all__ = [
    "CONNECT_TIMEOUT",
    "LOCK_NAME",
    "MAX_TASKS",
    "MAX_VARIANTS",
    "CampaignError",
    "CampaignInputError",
    "CampaignSpec",
    "check_scheduler_address",
    "plan_tasks",
    "run_campaign",
    "run_task",
]

#: Most variants of a campaign. Every variant's scenario is validated before anything runs
#: (about 40 ms each for the paper scenario: 10 000 variants take some 7 minutes).
MAX_VARIANTS = 10_000

#: Most tasks of a campaign (variants times ``ceil(seeds.count / batch_size)``): each task
#: is a Dask future carrying its variant's scenario, held by this process and the scheduler.
MAX_TASKS = 100_000

#: Seconds to wait for a scheduler to answer before giving up, by default.
CONNECT_TIMEOUT = 10.0

#: Shortest and longest wait for a scheduler that may be asked for, s.
MIN_CONNECT_TIMEOUT = 0.1
MAX_CONNECT_TIMEOUT = 3600.0

#: Longest text of a value or of a worker's error quoted in a message, characters.
_QUOTE = 200

#: The lock file of a campaign folder (hidden: Parquet readers skip it).
LOCK_NAME = ".crlbswarm-sweep.lock"


def _quote(value: Any) -> str:
    """A value as quoted in a campaign's messages (a path or an address fits whole)."""
    return _v.short(value, _QUOTE)


class CampaignInputError(CampaignError, ValueError):
    """A campaign task failed because of its input (the variant's scenario or its seeds):
    an error the user can fix, one line naming the variant and the seeds. The command line
    exits with status 2 (1 for a :class:`~crlbswarm.errors.CampaignError` of the cluster)."""


def _is_file(path: str | Path) -> bool:
    """``Path.is_file`` that answers False for a name too long or holding a NUL byte."""
    try:
        return Path(path).is_file()
    except (OSError, ValueError):
        return False


#: Most worker processes of a local cluster (each is a Python process with its own copy of
#: the compiled simulator: more than a few per core only adds memory and start-up time).
MAX_LOCAL_WORKERS = 4 * (os.cpu_count() or 1)

#: Memory of one worker process of a local cluster, bytes (measured: about 250 MB).
WORKER_BYTES = 300 * 2**20


class SeedRange(ConfigModel):
    """Seeds ``start, start + 1, ..., start + count - 1`` for every variant."""

    start: Annotated[int, Field(ge=0)] = Field(0, description="first seed")
    count: Annotated[int, Field(ge=1)] = Field(description="number of seeds per variant")

    @model_validator(mode="after")
    def _in_range(self) -> SeedRange:
        _v.seed_range(self.start, self.count, "seeds.start", "seeds.count")
        return self


class Distribution(ConfigModel):
    """A random field value: ``uniform = [low, high]`` or ``choice = [a, b, ...]``."""

    uniform: Annotated[list[float], Field(min_length=2, max_length=2)] | None = Field(
        None, description="[low, high]: drawn uniformly"
    )
    choice: Annotated[list[Any], Field(min_length=1)] | None = Field(
        None, description="values, one drawn with equal probabilities"
    )

    @field_validator("uniform")
    @classmethod
    def _bounds(cls, value: list[float] | None) -> list[float] | None:
        if value is not None:
            low, high = value
            if not (math.isfinite(low) and math.isfinite(high)):
                raise ValueError(f"the bounds must be finite, got {_quote(value)}")
            if low > high:
                raise ValueError(f"low must be at most high, got {_quote(value)}")
            if not math.isfinite(high - low):
                raise ValueError(f"the span high - low overflows, got {_quote(value)}")
        return value

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
        False,
        description="also save each task's result with its trajectories (a folder "
        "read by load_results)",
    )

    @model_validator(mode="after")
    def _variants(self) -> CampaignSpec:
        if self.grid is not None and self.random is not None:
            raise ValueError("give at most one of 'grid' and 'random'")
        self._check_sizes()
        return self

    def n_variants(self) -> int:
        """The number of variants, counted without building them.

        Returns
        -------
        int
            The product of the grid's lengths, ``random.samples``, or 1.
        """
        if self.grid is not None:
            return math.prod(len(values) for values in self.grid.values())
        return self.random.samples if self.random is not None else 1

    def n_tasks(self) -> int:
        """The number of tasks: variants times ``ceil(seeds.count / batch_size)``.

        Returns
        -------
        int
            The count, computed without building the tasks.
        """
        return self.n_variants() * -(-self.seeds.count // self.batch_size)

    def _check_sizes(self) -> None:
        """Refuse, before anything is built, more than :data:`MAX_VARIANTS` variants or
        :data:`MAX_TASKS` tasks (the message gives the count, the limit and the remedy)."""
        n = self.n_variants()
        if n > MAX_VARIANTS:
            if self.grid is not None:
                lengths = " x ".join(str(len(v)) for v in self.grid.values())
                field, count = "grid", f"the grid makes {lengths} = {n:,} variants"
            else:
                field, count = "random.samples", f"{n:,} variants"
            raise FieldError(
                field,
                f"{one_line(count, _QUOTE)}, more than the limit of {MAX_VARIANTS:,} (each "
                "variant's "
                "scenario is validated before anything runs); split the campaign into "
                "several specs",
            )
        tasks = self.n_tasks()
        if tasks > MAX_TASKS:
            raise FieldError(
                "seeds.count",
                f"{n:,} variants x {self.seeds.count:,} seeds in tasks of {self.batch_size:,} "
                f"runs make {tasks:,} tasks, more than the limit of {MAX_TASKS:,} (each task "
                "is a Dask future); raise batch_size or run fewer seeds",
            )

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
        # A file beside the spec is its base; so is anything else of that name (refused
        # later as not a regular file), unless the name is a built-in scenario's.
        if not Path(spec.base).is_absolute() and (
            beside.is_file() or (os.path.lexists(beside) and spec.base not in BUILTIN_SCENARIOS)
        ):
            spec = spec.model_copy(update={"base": str(beside)})
        return spec, text

    def base_dict(self) -> dict[str, Any]:
        """The base scenario as a dictionary (built-in, or read from its TOML file).

        Returns
        -------
        dict
            Scenario data, ready for :meth:`crlbswarm.Scenario.from_dict`.
        """
        if self.base not in BUILTIN_SCENARIOS and not _is_file(self.base):
            known = ", ".join(BUILTIN_SCENARIOS)
            if os.path.lexists(self.base):  # a folder, a device, a FIFO, a dangling link
                raise FieldError("base", f"{_quote(self.base)} is not a regular file")
            raise FieldError(
                "base",
                f"{_quote(self.base)} is neither a built-in scenario ({known}) nor a file",
            )
        try:
            return scenario_data(self.base)[1]
        except ScenarioError as exc:  # a file that cannot be read or parsed
            raise FieldError("base", one_line(str(exc), 5 * _QUOTE)) from None

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
    FieldError
        If one task's arrays would not fit in memory (``batch_size``).
    """
    base = spec.base_dict()
    scenarios = []
    largest = 0
    for i, changes in enumerate(spec.variants()):
        data = _apply(base, changes, "random.fields" if spec.random is not None else "grid")
        source = f"variant {i} ({_label(changes)})"
        scenario = Scenario.from_dict(data, source=source)
        if scenario.extra_targets:
            raise ScenarioError(
                source, "extra_targets", "campaigns fly one target per mission; several "
                "targets are flown by crlbswarm simulate (or simulate_groups)",
            )  # fmt: skip
        need = _task_bytes(scenario, min(spec.batch_size, spec.seeds.count), spec.trajectories)
        if need > largest:  # the check reads /proc: only when a variant needs more
            largest = need
            _check_task_memory(need, spec, scenario.time.steps)
        scenarios.append(data)
    first, count = spec.seeds.start, spec.seeds.count
    tasks = [
        (v, s, min(s + spec.batch_size, first + count) - 1)
        for v in range(len(scenarios))
        for s in range(first, first + count, spec.batch_size)
    ]
    return scenarios, tasks


def _task_bytes(scenario: Scenario, runs: int, trajectories: bool) -> int:
    """Memory of a task of ``runs`` runs on its worker: the estimate of
    :func:`crlbswarm.simulate` (14 time series of float64 per step and run, and the
    positions and velocities when they are kept)."""
    steps = scenario.time.steps + 1
    series = runs * steps * 14 * 8
    return series + (2 * runs * steps * scenario.uavs.count * 2 * 8 if trajectories else 0)


def _check_task_memory(need: int, spec: CampaignSpec, steps: int) -> None:
    runs = min(spec.batch_size, spec.seeds.count)
    try:
        _v.check_memory(need, "batch_size", f"the {runs:,} runs of {steps:,} steps of a task")
    except FieldError as exc:
        raise FieldError("batch_size", f"{exc.reason}; lower batch_size") from None


def _label(changes: dict[str, Any]) -> str:
    text = ", ".join(f"{k}={v}" for k, v in changes.items()) or "base"
    return one_line(text, _QUOTE)


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
        Keep the trajectories, and also return the whole result.

    Returns
    -------
    dict
        ``columns`` (metric name to 1-D array, with ``variant`` and ``seed``) and, with
        ``trajectories``, ``result`` (the :class:`crlbswarm.MissionResult`).
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
        out["result"] = result
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
    table: dict[str, Any] = {}
    for name, values in columns.items():
        if name == "variant":
            continue
        values = np.asarray(values)
        # A quantity that does not exist for a run (the convergence time of a run that did
        # not converge, the clearance without obstacles) is null, not NaN or inf.
        mask = ~np.isfinite(values) if values.dtype.kind == "f" else None
        table[name] = pa.array(values, mask=mask)
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
    tls_ca_file: str | Path | None = None,
    tls_cert: str | Path | None = None,
    tls_key: str | Path | None = None,
    connect_timeout: float = CONNECT_TIMEOUT,
) -> dict[str, int]:
    """Run (or resume) a campaign on Dask and write its Parquet dataset under ``out``.

    Everything is checked before the folder is touched: the spec and every variant, the
    sizes, the scheduler's address and the TLS files; then the cluster is started (or the
    scheduler reached), and only then is the folder created and locked.

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.
    out : str or path-like
        Output folder (created if missing).
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:port`` or ``tls://host:port``);
        by default a local cluster is started on this machine, listening on 127.0.0.1 only,
        and closed at the end.
    n_workers : int, optional
        Workers of the local cluster (default: one per core).
    spec_text : str, optional
        The spec's TOML text, saved as ``spec.toml``.
    progress : callable, optional
        Called with (finished tasks, total tasks) after each task.
    tls_ca_file : str or path-like, optional
        With a ``tls://`` scheduler: the certificate authority that signed the certificates
        of the scheduler and its workers (PEM). If missing, Dask's configuration
        ``distributed.comm.tls.ca-file``. Encryption is then required.
    tls_cert : str or path-like, optional
        With a ``tls://`` scheduler: this client's certificate (PEM); if missing,
        ``distributed.comm.tls.client.cert``.
    tls_key : str or path-like, optional
        With a ``tls://`` scheduler: this client's private key (PEM; if missing,
        ``distributed.comm.tls.client.key``, or the key is in ``tls_cert``).
    connect_timeout : float, default CONNECT_TIMEOUT
        Seconds to wait for the scheduler.

    Returns
    -------
    dict
        ``variants``, ``tasks``, ``skipped`` (already finished) and ``ran`` task counts.

    Raises
    ------
    FieldError
        For an invalid spec, size, address or file, an unreachable scheduler, or a folder
        holding another campaign or in use by another process; nothing is written.
    CampaignInputError
        If a task fails because of its input (the variant's runs diverge, for example).
    CampaignError
        If the cluster fails (a worker lost too often, the local cluster not starting).
    """
    if n_workers is not None:
        _v.count(n_workers, "n_workers", 1)
        if n_workers > MAX_LOCAL_WORKERS:
            raise FieldError(
                "n_workers",
                f"{n_workers} worker processes on this machine is more than the "
                f"{MAX_LOCAL_WORKERS} allowed (it has {os.cpu_count() or 1} cores)",
            )
        _v.check_memory(n_workers * WORKER_BYTES, "n_workers", f"{n_workers} worker processes")
    timeout = _v.positive_scalar(connect_timeout, "connect_timeout")
    if not MIN_CONNECT_TIMEOUT <= timeout <= MAX_CONNECT_TIMEOUT:
        raise FieldError(
            "connect_timeout",
            f"must be between {MIN_CONNECT_TIMEOUT:g} and {MAX_CONNECT_TIMEOUT:g} s, "
            f"got {timeout:g}",
        )
    address = None if scheduler is None else check_scheduler_address(scheduler)
    security = _security(address, tls_ca_file, tls_cert, tls_key)
    if address is not None:
        _probe(address, timeout)  # a closed port or an unknown host: refused at once
    folder = Path(out)
    check_output_folder(folder, "out")
    scenarios, tasks = plan_tasks(spec)  # validate everything before anything runs
    variants = spec.variants()
    table = _variants_table(variants)
    canonical = _canonical(spec)
    _check_same_campaign(folder, canonical)
    _check_not_in_use(folder)
    digest = hashlib.sha256(canonical.encode()).hexdigest()[:16]

    def report(done: int) -> None:
        if progress is not None:
            progress(done, len(tasks))

    with contextlib.ExitStack() as stack:

        def connect() -> Any:
            return stack.enter_context(_dask_client(address, n_workers, security, timeout))

        # The cluster is up before the folder is touched: a scheduler that cannot be reached
        # leaves nothing behind. No cluster when every task is already done.
        client = connect() if _unfinished(folder, tasks) else None
        stack.enter_context(_locked(folder))
        _prepare_folder(folder, canonical, table, spec_text)
        todo = _unfinished(folder, tasks)  # under the lock: the folder's true state
        finished = len(tasks) - len(todo)
        report(finished)
        if todo:
            client = client or connect()
            _run_tasks(client, spec, folder, scenarios, variants, todo, table.schema,
                       digest, report, finished)  # fmt: skip
    return {"variants": len(variants), "tasks": len(tasks), "skipped": finished, "ran": len(todo)}


def _unfinished(folder: Path, tasks: list[tuple[int, int, int]]) -> list[tuple[int, int, int]]:
    return [t for t in tasks if not _part_path(folder, *t).is_file()]


def check_scheduler_address(address: str) -> str:
    """Check the syntax of a Dask scheduler's address, without connecting.

    Parameters
    ----------
    address : str
        ``tcp://host:port`` or ``tls://host:port`` (``host:port`` means ``tcp://``; an IPv6
        host is written in brackets, ``tcp://[::1]:8786``).

    Returns
    -------
    str
        The address with its scheme.

    Raises
    ------
    FieldError
        Naming ``scheduler``: an empty address, another scheme (``inproc://`` only works
        inside the process that created it), or a missing or invalid host or port.
    """
    if not isinstance(address, str):
        raise FieldError("scheduler", f"expected an address string, got {_quote(address)}")
    usage = "give tcp://host:port or tls://host:port, or no address to start a local cluster"
    if not address.strip():
        raise FieldError("scheduler", f"empty address; {usage}")
    scheme, sep, rest = address.partition("://")
    scheme, rest = (scheme.lower(), rest) if sep else ("tcp", address)
    if scheme == "inproc":
        raise FieldError(
            "scheduler",
            f"{_quote(address)}: an inproc:// address only works inside the process that "
            f"created it; {usage}",
        )
    if scheme not in ("tcp", "tls"):
        raise FieldError("scheduler", f"{_quote(address)}: unsupported scheme {_quote(scheme)}; "
                         f"{usage}")  # fmt: skip
    try:
        parts = urlsplit(f"//{rest}")
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if (
        any(c.isspace() or not c.isprintable() for c in rest)
        or not host
        or not port
        or parts.username is not None
        or parts.path
        or parts.query
        or parts.fragment
    ):
        raise FieldError("scheduler", f"{_quote(address)} is not host:port with a port in "
                         f"1..65535; {usage}")  # fmt: skip
    if len(host) > 253:  # (not host: checked above)
        raise FieldError("scheduler", f"{_quote(address)}: the host name is longer than 253 "
                         "characters")  # fmt: skip
    return f"{scheme}://{rest}"


def _security(
    address: str | None, ca_file: str | Path | None, cert: str | Path | None,
    key: str | Path | None,
) -> Any:  # fmt: skip
    """The Dask ``Security`` of a ``tls://`` scheduler (encryption required), or None."""
    given = {"tls_ca_file": ca_file, "tls_cert": cert, "tls_key": key}
    named = {name: str(path) for name, path in given.items() if path is not None}
    if address is None or not address.startswith("tls://"):
        if named:
            where = "the local cluster" if address is None else _quote(address)
            raise FieldError(next(iter(named)), f"TLS files need a tls://host:port scheduler "
                             f"(not {where})")  # fmt: skip
        return None
    for name, path in named.items():
        if not (_is_file(path) and os.access(path, os.R_OK)):
            raise FieldError(name, f"{_quote(path)} is not a readable regular file")
    from distributed.security import Security

    renamed = {"tls_ca_file": "tls_ca_file", "tls_cert": "tls_client_cert",
               "tls_key": "tls_client_key"}  # fmt: skip
    security = Security(require_encryption=True, **{renamed[k]: v for k, v in named.items()})
    for name, attribute in (("tls_ca_file", "tls_ca_file"), ("tls_cert", "tls_client_cert")):
        if not getattr(security, attribute):
            raise FieldError(
                name,
                "a tls:// scheduler needs the certificate authority's file and this client's "
                "certificate and key (--tls-ca-file, --tls-cert, --tls-key, or Dask's "
                "distributed.comm.tls.* configuration)",
            )
    return security


@contextlib.contextmanager
def _quiet_distributed() -> Iterator[None]:
    """Silence Dask's own log lines while a campaign runs: failures are reported once, as
    one line, by the campaign."""
    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


@contextlib.contextmanager
def _dask_client(
    address: str | None, n_workers: int | None, security: Any, timeout: float
) -> Iterator[Any]:
    """A client of a local cluster listening on 127.0.0.1 only (closed at the end), or of
    the scheduler at ``address``, reached within ``timeout`` seconds."""
    from dask.distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        stack.enter_context(_quiet_distributed())
        if address is None:
            try:
                target: Any = stack.enter_context(LocalCluster(
                    n_workers=n_workers, threads_per_worker=1, processes=True,
                    host="127.0.0.1",  # scheduler, nannies and workers: never other interfaces
                    dashboard_address="127.0.0.1:0",  # any free port, loopback only
                    silence_logs=logging.CRITICAL,
                ))  # fmt: skip
            except Exception as exc:
                raise CampaignError(
                    f"the local cluster did not start: {_error_text(exc)}"
                ) from None
        else:
            target = address
        try:
            # (the local cluster runs here: it gets the default wait, not the user's)
            wait = timeout if address is not None else max(timeout, CONNECT_TIMEOUT)
            client = Client(target, timeout=wait, security=security)
        except Exception as exc:  # OSError, TimeoutError, ssl.SSLError, a foreign server...
            if address is None:
                raise CampaignError(f"the local cluster: {_error_text(exc)}") from None
            raise FieldError(
                "scheduler",
                f"cannot connect to {_quote(address)} (a Dask scheduler, of the same "
                f"scheme?): {_error_text(exc)}",
            ) from None
        yield stack.enter_context(client)


def _probe(address: str, timeout: float) -> None:
    """Open and close a TCP connection to the scheduler: a closed port or an unknown host is
    refused at once (Dask itself would retry until its timeout)."""
    parts = urlsplit("//" + address.partition("://")[2])
    try:
        socket.create_connection((parts.hostname, parts.port or 0), timeout=timeout).close()
    except (OSError, UnicodeError) as exc:  # UnicodeError: a host name idna cannot encode
        reason = getattr(exc, "strerror", None) or _error_text(exc)
        raise FieldError("scheduler", f"cannot connect to {_quote(address)}: {reason}") from None


def _error_text(exc: BaseException) -> str:
    """An exception as one short line: its type and its message's first few hundred
    characters (a worker's error never brings its traceback or a megabyte value)."""
    text = one_line(str(exc), _QUOTE)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _in_use(folder: Path, fd: int) -> FieldError | None:
    """Try to lock the open lock file ``fd`` (``flock``, exclusive, without waiting); the
    error to raise if another process holds it, None once locked."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
        return FieldError(
            "out",
            f"{_quote(str(folder))} is in use by another crlbswarm sweep (pid {pid})",
        )
    except OSError as exc:
        return FieldError("out", f"cannot lock {_quote(str(folder))}: {exc.strerror}")
    return None


def _check_not_in_use(folder: Path) -> None:
    """Refuse at once, before starting a cluster, a folder another sweep holds (the lock is
    taken for good, and checked again, by :func:`_locked`)."""
    try:  # (non-blocking: a FIFO in its place must not hang the command)
        fd = os.open(folder / LOCK_NAME, os.O_RDONLY | os.O_CLOEXEC | os.O_NONBLOCK)
    except OSError:  # no lock file: no campaign ever ran here
        return
    try:
        error = _in_use(folder, fd)
    finally:
        os.close(fd)  # releases the lock, if taken
    if error is not None:
        raise error


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """Create ``folder`` and hold an exclusive lock on its lock file (``flock``, released
    when the process ends, even by ``kill -9``); refuse a folder locked by another process.
    The lock file stays (removing it would let two processes lock two different files)."""
    folder.mkdir(parents=True, exist_ok=True)
    fd = os.open(folder / LOCK_NAME, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NONBLOCK, 0o644)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise FieldError("out", f"{LOCK_NAME} in {_quote(str(folder))} is not a regular file")
        error = _in_use(folder, fd)
        if error is not None:
            raise error
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)


def _variants_table(variants: list[dict[str, Any]]) -> Any:
    """The Arrow table of ``variants.parquet``: the variant id and every changed field."""
    import pyarrow as pa

    rows: dict[str, list[Any]] = {"variant": list(range(len(variants)))}
    for name in sorted({k for v in variants for k in v}):
        rows[name] = [v.get(name) for v in variants]
    try:
        return pa.table(rows)
    except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
        raise FieldError(
            "grid", f"the values of a field must share one type ({one_line(str(exc), _QUOTE)})"
        ) from None


def _canonical(spec: CampaignSpec) -> str:
    """The spec and its resolved base scenario (an edited base file is another campaign)."""
    return json.dumps(
        {"spec": spec.model_dump(), "base": spec.base_dict(), "crlbswarm": __version__},
        sort_keys=True,
    )


def _check_same_campaign(folder: Path, canonical: str) -> None:
    """Refuse a folder holding another campaign: resuming into it would mix two datasets."""
    marker = folder / "spec.json"
    if not os.path.lexists(marker):
        if folder.is_dir() and any(not e.name.startswith(".") for e in folder.iterdir()):
            raise FieldError(
                "out",
                f"{_quote(str(folder))} holds files but no campaign (no spec.json); use a new "
                "or empty folder",
            )
        return
    expected = canonical.encode()
    try:
        if not stat.S_ISREG(os.lstat(marker).st_mode):  # a FIFO would block the read
            raise OSError("not a regular file")
        with open(marker, "rb") as f:  # read no further than needed
            same = f.read(len(expected) + 1) == expected
    except OSError:
        same = False
    if not same:
        raise FieldError(
            "out",
            f"{_quote(str(folder))} holds the results of a different campaign (its spec.json "
            "differs); use another folder",
        )


def _prepare_folder(folder: Path, canonical: str, table: Any, spec_text: str | None) -> None:
    """Under the folder's lock: check again that it holds this campaign (or nothing), write
    its spec and variants table, and remove the temporaries of interrupted writes."""
    import pyarrow.parquet as pq

    _check_same_campaign(folder, canonical)
    # Temporaries of files interrupted while being written (hidden files, which Parquet
    # readers skip) are stale: no other process writes here while we hold the lock.
    for pattern in (".spec.json.*", ".spec.toml.*", ".variants.parquet.*", "runs/*/.part-*",
                    "trajectories/*/.part-*"):  # fmt: skip
        for stale in folder.glob(pattern):
            stale.unlink(missing_ok=True)
    for pattern in (f"trajectories/*/{STAGE_PREFIX}*", f"trajectories/*/*/{STAGE_PREFIX}*"):
        for stale in folder.glob(pattern):  # results of tasks interrupted while being saved
            shutil.rmtree(stale, ignore_errors=True)
    write_text(folder / "spec.json", canonical)
    if spec_text is not None:
        write_text(folder / "spec.toml", spec_text)
    with atomic_path(folder / "variants.parquet") as tmp:
        pq.write_table(table, tmp)


def _task_failure(
    exc: BaseException, v: int, a: int, b: int, changes: dict[str, Any]
) -> CampaignError:
    """The one-line error of a failed task: the user's input (a ``ValueError`` or a diverged
    run, raised by the simulator) or the cluster (a worker lost, anything else)."""
    if isinstance(exc, ValueError | SimulationDivergedError):
        return CampaignInputError(f"variant {v} ({_label(changes)}), seeds {a}..{b}: "
                                  f"{one_line(str(exc), 2 * _QUOTE)}")  # fmt: skip
    return CampaignError(f"variant {v}, seeds {a}..{b}: {_error_text(exc)}")


def _run_tasks(client: Any, spec: CampaignSpec, folder: Path, scenarios: list[dict[str, Any]],
               variants: list[dict[str, Any]], todo: list[tuple[int, int, int]], schema: Any,
               digest: str, progress: Callable[[int], None], done: int) -> None:  # fmt: skip
    """Run the unfinished tasks on Dask and write each one's files as it finishes; report
    the count of finished tasks (``done`` before the first) to ``progress``."""
    from dask.distributed import as_completed

    # Deterministic failures are not retried (they would fail again); a task whose worker
    # dies is rescheduled by Dask (distributed.scheduler.allowed-failures).
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
        except Exception as exc:  # every failure becomes one line
            raise _task_failure(exc, v, a, b, variants[v]) from None
        future.release()  # do not keep finished results on the workers
        path = _part_path(folder, v, a, b)
        # The Parquet part is written last: its presence marks the task done.
        if spec.trajectories:  # the folder simulate writes (staged: absent or complete)
            part = folder / "trajectories" / path.parent.name / path.stem
            result["result"].save(part, overwrite=True)
        _write_part(path, result["columns"], variants[v], schema)
        del result
        done += 1
        progress(done)
