"""Seeded fuzzing of what a user can feed crlbswarm: scenario files, campaign specs, command
lines and public functions.

Each case mutates a valid input in one of the classes that broke before (sizes that cannot
fit, numbers at the edge of double precision, NaN and infinities, wrong types, huge strings,
deep nesting, odd files, odd addresses) and runs it in a worker process under a memory cap
(``RLIMIT_AS``); a case that does not answer in time, or kills the worker, is a failure and
the worker is restarted. The contract, checked case by case:

* a command line ends with exit status 2, exactly one line on stderr
  (``crlbswarm: error: ...``), no traceback and nothing written; or it succeeds (status 0)
  and every number it reports (stdout, ``metrics.csv``, ``summary.json``) is finite;
* a public function raises a ``ValueError`` with a one-line message, or returns finite
  numbers (the CRLB of an exactly singular geometry, documented as ``inf``, is allowed);
* no case takes more than :data:`CASE_SECONDS`; no ``MemoryError``, no "internal error".

Run on demand (the test suite runs a short, fixed-seed version in a subprocess)::

    python tests/fuzzing.py --cases 2000 --seed 1
    python tests/fuzzing.py --cases 200 --family scenario --verbose

It prints one JSON line per failing case and a summary line; exit status 1 if any failed.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import math
import os
import random
import re
import resource
import selectors
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: Longest a case may take, s (``CRLBSWARM_FUZZ_CASE_SECONDS`` changes it: the test suite
#: makes it a hang guard only, since its first case of a kind may compile the simulator on a
#: cold cache, on a loaded machine).
CASE_SECONDS = float(os.environ.get("CRLBSWARM_FUZZ_CASE_SECONDS", "10"))

#: Memory cap of the fuzzing process (address space), bytes.
MEMORY_CAP = 4 * 2**30

#: Numbers that break naive arithmetic.
EXTREME = [1e308, -1e308, 1e300, 1e-300, 5e-324, -5e-324, 0.0, -0.0, -1.0, 1e15, 1e-15, 0.5]
#: Integers beyond any sensible size.
HUGE_INTS = [10**5, 10**6, 10**7, 10**9, 10**12, 2**63 - 1, 2**63, 2**64, -(2**63)]
#: Values of the wrong type.
WRONG = ["text", True, [], {}, [1.0, 2.0, 3.0], "1e3", ""]
NONFINITE = [math.nan, math.inf, -math.inf]

_NUMBER = re.compile(r"(?<![\w.])(nan|inf|-inf|infinity)(?![\w])", re.IGNORECASE)


# -- generators ----------------------------------------------------------------------------
def _leaves(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Paths of every value (tables, lists and scalars) of a TOML document."""
    out: list[tuple[Any, ...]] = []
    if isinstance(data, dict):
        for key, value in data.items():
            out.append((*prefix, key))
            out += _leaves(value, (*prefix, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            out.append((*prefix, i))
            out += _leaves(value, (*prefix, i))
    return out


def _set(data: Any, path: tuple[Any, ...], value: Any) -> None:
    for key in path[:-1]:
        data = data[key]
    if value is _DELETE:
        del data[path[-1]]
    else:
        data[path[-1]] = value


_DELETE = object()


def _value(rng: random.Random) -> Any:
    """A value from one of the classes."""
    kind = rng.choice(["extreme", "extreme", "huge", "wrong", "nonfinite", "string", "nest"])
    if kind == "extreme":
        return rng.choice(EXTREME)
    if kind == "huge":
        return rng.choice(HUGE_INTS)
    if kind == "wrong":
        return copy.deepcopy(rng.choice(WRONG))
    if kind == "nonfinite":
        return rng.choice(NONFINITE)
    if kind == "string":
        return "x" * rng.choice([10_000, 1_000_000])
    depth = rng.choice([20, 200])
    value: Any = 1.0
    for _ in range(depth):
        value = [value]
    return value


def _scenario_mutation(rng: random.Random, data: dict[str, Any]) -> str:
    """Mutate a scenario document in place; return a description."""
    targeted = [
        # (10**5 UAVs is a valid swarm that takes minutes to fly: the limit plus one is not)
        ("uavs.count", rng.choice([10**5 + 1, 10**6, 10**7, 10**9])),
        ("eta.samples", rng.choice([10**6, 10**9, 10**12])),
        ("time.duration", rng.choice([1e308, 1e15, 1e9])),
        ("time.step", rng.choice([1e-300, 5e-324, 1e-9, 1e300])),
        ("target", [rng.choice([1e300, 1e7, -1e308]), 0.0]),
        ("altitude", rng.choice([1e-300, 5e-324, 1e308, 1e6])),
        ("radar.kappa", rng.choice([5e-324, 1e-300, 1e300])),
        ("radar.noise_power", rng.choice([1e-300, 5e-324, 1e300])),
        ("radar.tx_power", rng.choice([1e-300, 1e300])),
        ("disturbance.sigma", rng.choice([1e300, 1e6, 1e3])),
        ("control.epsilon", rng.choice([1e300, 1e-300, 5e-324])),
        ("control.kg", rng.choice([1e300, 1e-300])),
        ("graph", {"kind": "complete"}),
        ("obstacles", [{"type": "circle", "center": [500.0 + 3 * i, 500.0], "radius": 1.0}
                       for i in range(rng.choice([300, 20_000]))]),
    ]  # fmt: skip
    roll = rng.random()
    if roll < 0.35:
        dotted, value = rng.choice(targeted)
        path = tuple(dotted.split("."))
        node = data
        for key in path[:-1]:
            node = node.setdefault(key, {})
        if dotted == "graph" and rng.random() < 0.7:
            data.setdefault("uavs", {})["count"] = rng.choice([10**4, 10**5])
        node[path[-1]] = value
        return f"{dotted}={_short(value)}"[:120]
    paths = _leaves(data)
    path = rng.choice(paths)
    if roll < 0.45:
        _set(data, path, _DELETE)
        return f"del {_dotted(path)}"
    if roll < 0.5:
        data[rng.choice(["unknown", "uavs"])] = {"bogus": 1}
        return "unknown key"
    value = _value(rng)
    _set(data, path, value)
    return f"{_dotted(path)}={_short(value)}"


def _campaign_mutation(rng: random.Random, spec: dict[str, Any]) -> tuple[str, list[str]]:
    """Mutate a campaign spec in place; return a description and extra sweep options."""
    options: list[str] = []
    choices: list[Callable[[], str]] = [
        lambda: _put(spec, ("seeds", "count"), rng.choice([10**6, 10**9, 10**12, 0, -1])),
        lambda: _put(spec, ("seeds", "start"), rng.choice([2**63 - 1, 2**63, -1])),
        lambda: _put(spec, ("grid",), {f"f{i}": list(range(100)) for i in range(5)}),
        lambda: _put(spec, ("grid",), {"altitude": [rng.choice(EXTREME + NONFINITE)]}),
        lambda: _put(spec, ("grid",), {"uavs.count": [rng.choice(HUGE_INTS)]}),
        lambda: _put(
            spec,
            ("random",),
            {
                "samples": rng.choice([10**5, 10**6, 10**9]),
                "fields": {"altitude": {"choice": [20]}},
            },
        ),
        lambda: _put(
            spec,
            ("random",),
            {
                "samples": 2,
                "fields": {
                    "altitude": {
                        "uniform": rng.choice(
                            [[math.nan, 1.0], [0.0, math.inf], [30.0, 20.0], [-math.inf, 5.0]]
                        )
                    }
                },
            },
        ),
        lambda: _put(
            spec, ("base",), rng.choice(["/dev/zero", "/nonexistent.toml", "/tmp", "x" * 5000])
        ),
        lambda: _put(spec, ("batch_size",), rng.choice([0, -1, 10**12, 1.5])),
        lambda: _put(spec, ("trajectories",), rng.choice(["yes", 1, None])),
    ]
    if rng.random() < 0.3:
        address = rng.choice(["", "inproc://x", "tcp://", "garbage", "tcp://127.0.0.1:99999"])
        options = ["--scheduler", address]
        return f"scheduler={address!r}", options
    if rng.random() < 0.2:
        options = ["--workers", str(rng.choice([0, -1, 10**6]))]
        return f"workers={options[1]}", options
    return rng.choice(choices)(), options


def _put(data: dict[str, Any], path: tuple[str, ...], value: Any) -> str:
    node = data
    for key in path[:-1]:
        node = node.setdefault(key, {})
    if value is None:
        node.pop(path[-1], None)
    else:
        node[path[-1]] = value
    return f"{'.'.join(path)}={_short(value)}"


def _cli_case(rng: random.Random, tmp: Path) -> list[str]:
    """A command line with at least one odd argument."""
    bad_number = lambda: rng.choice(  # noqa: E731
        ["nan", "inf", "-inf", "1e308", "-1e308", "5e-324", "1e-300", "x", "", "0", "-1", "1e999"]
    )
    bad_int = lambda: rng.choice(  # noqa: E731
        ["0", "-1", "1000000000", str(2**63), str(2**70), "1.5", "x", "", "1e3"]
    )
    existing_file = tmp / "afile"
    existing_file.write_text("x")
    full = tmp / "full"
    full.mkdir(exist_ok=True)
    (full / "keep.txt").write_text("mine")
    bad_out = rng.choice([str(existing_file), str(full), str(existing_file / "sub"), ""])
    command = rng.choice(["design", "simulate", "figures", "scenario", "sweep", "none", "bogus"])
    if command == "none":
        return []
    if command == "bogus":
        return [rng.choice(["bogus", "--bogus", "-x"])]
    if command == "design":
        args = ["design"]
        option = rng.choice(
            ["--uavs", "--altitude", "--rotation", "--target", "--tx-power", "--tx-power-dbm",
             "--noise-power", "--kappa", "--frequency", "--rcs-dbsm", "constrained"]
        )  # fmt: skip
        if option == "constrained":  # a constraint option with an odd value (few starts)
            odd = rng.choice(
                [["--obstacle", f"circle:0,0,{bad_number()}"], ["--obstacle", "rect:1"],
                 ["--no-fly", f"poly:0,0,1,{bad_number()},1,0"], ["--no-fly", "circle:"],
                 ["--clearance", bad_number()], ["--min-separation", bad_number()],
                 ["--max-radius", bad_number()], ["--altitude-band", f"{bad_number()}:30"],
                 ["--altitude-band", "10:20", "--altitude-band", "1:2"],
                 ["--criterion", rng.choice(["", "X", "ad", "e"])], ["--starts", bad_int()],
                 ["--seed", bad_int()], ["--target", "0,0", "--target", bad_number() + ",1"],
                 ["--objective", "min"], ["--scenario", rng.choice(["nope", str(tmp)])],
                 ["-o", bad_out], ["-o", str(existing_file)]]
            )  # fmt: skip
            return [*args, *odd, "--starts", "1"] if "--starts" not in odd else [*args, *odd]
        if option == "--uavs":
            return [*args, option, rng.choice([bad_int(), "100000", "2", "10000000"])]
        if option == "--target":
            return [*args, option, bad_number(), bad_number()]
        return [*args, option, bad_number()]
    if command == "figures":  # always something wrong: a valid run takes half a minute
        which = rng.choice(["out", "uavs", "seed", "format"])
        if which == "out":
            return ["figures", "--out", bad_out]
        if which == "format":
            return ["figures", "--out", str(tmp / "fig"), "--format", rng.choice(["jpg", ""])]
        value = bad_int() if which == "uavs" else rng.choice(["-1", str(2**63), "x"])
        if which == "uavs" and value not in ("0", "-1", "1.5", "x", "", "1e3"):
            value = "2"
        return ["figures", "--out", str(tmp / "fig"), f"--{which}", value]
    if command == "scenario":
        return [
            "scenario",
            "show",
            rng.choice(["/dev/zero", "/nonexistent", str(tmp), "x" * 3000]),
        ]
    if command == "sweep":
        return ["sweep", str(tmp / "missing.toml"), "--out", str(tmp / "sw")]
    out = str(tmp / "sim")
    which = rng.choice(["runs", "seed", "out", "scenario", "runs"])
    if which == "runs":
        return ["simulate", "paper", "--out", out, "--runs", bad_int()]
    if which == "seed":
        return ["simulate", "paper", "--out", out, "--seed", bad_int()]
    if which == "out":
        return ["simulate", "paper", "--out", bad_out]
    return ["simulate", rng.choice(["/dev/zero", "nonexistent", str(tmp)]), "--out", out]


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) < 80 else f"{text[:60]}...({len(text)} chars)"


def _dotted(path: tuple[Any, ...]) -> str:
    return ".".join(str(p) for p in path)


# -- running and judging -------------------------------------------------------------------
def _run_cli(argv: list[str]) -> tuple[Any, str, str]:
    """Run the CLI in this process; (status or exception text, stdout, stderr)."""
    from crlbswarm.cli import main

    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status: Any = main(argv)
    except SystemExit as exc:  # argparse
        status = exc.code
    return status, out.getvalue(), err.getvalue()


def _snapshot(paths: list[Path]) -> dict[str, Any]:
    """What exists under each path (to tell whether anything was written)."""
    shot = {}
    for path in paths:
        if path.is_dir():
            shot[str(path)] = sorted(str(p) for p in path.rglob("*"))
        else:
            shot[str(path)] = path.exists()
    return shot


def judge_cli(status: Any, stdout: str, stderr: str, before: Any, after: Any,
              outputs: list[Path]) -> str | None:  # fmt: skip
    """The problem of a command-line case, or None."""
    lines = stderr.splitlines()
    if "Traceback" in stderr:
        return "traceback"
    if any(word in stderr for word in ("internal error", "not enough memory", "recursion")):
        return "uncaught: " + lines[-1][:200]
    if status == 2:
        if len(lines) != 1 or not lines[0].startswith("crlbswarm: error:"):
            return f"{len(lines)} stderr lines"
        if before != after:
            return "wrote output on error"
        return None
    if status == 0:
        if any(not line.startswith("crlbswarm: warning:") for line in lines):
            return "stray stderr line"
        if _NUMBER.search(stdout):
            return "non-finite number on stdout"
        for out in outputs:
            for name in ("metrics.csv", "summary.json"):
                path = out / name
                if path.exists() and _NUMBER.search(path.read_text()):
                    return f"non-finite number in {name}"
        return None
    return f"exit status {status!r}"


def scenario_case(rng: random.Random, tmp: Path) -> dict[str, Any]:
    """A mutated scenario file through ``crlbswarm simulate``."""
    import tomlkit

    from crlbswarm.scenario import BUILTIN_SCENARIOS

    name = rng.choice(list(BUILTIN_SCENARIOS))
    data = copy.deepcopy(BUILTIN_SCENARIOS[name])
    what = _scenario_mutation(rng, data)
    path = tmp / "scenario.toml"
    if "nest" in what or rng.random() < 0.05:
        text = "a = " + "[" * rng.choice([100, 100_000]) + "1" + "]" * 10
        what = "deeply nested text"
    else:
        try:
            text = tomlkit.dumps(data)
        except Exception:  # a value TOML cannot hold (e.g. an int beyond 64 bits)
            text = "x = 1\n" + json.dumps(_short(data))[:50]
    path.write_text(text)
    out = tmp / "out"
    argv = ["simulate", str(path), "--out", str(out), "--runs", str(rng.choice([1, 2]))]
    if rng.random() < 0.5:
        argv.append("--no-trajectories")
    return {"family": "scenario", "input": f"{name}: {what}", "argv": argv, "outputs": [out]}


def campaign_case(rng: random.Random, tmp: Path) -> dict[str, Any]:
    """A mutated campaign spec through ``crlbswarm sweep`` (a scheduler that is not there,
    so a valid spec ends quickly with one line instead of starting a cluster)."""
    import tomlkit

    spec: dict[str, Any] = {"base": "paper", "seeds": {"count": 2}, "batch_size": 2}
    what, options = _campaign_mutation(rng, spec)
    path = tmp / "spec.toml"
    try:
        path.write_text(tomlkit.dumps(spec))
    except Exception:
        path.write_text("base = 1\n")
    out = tmp / "campaign"
    argv = ["sweep", str(path), "--out", str(out)]
    argv += options or ["--scheduler", "tcp://127.0.0.1:9"]
    return {"family": "campaign", "input": what, "argv": argv, "outputs": [out]}


def cli_case(rng: random.Random, tmp: Path) -> dict[str, Any]:
    """An odd command line."""
    argv = _cli_case(rng, tmp)
    outputs = [tmp / "sim", tmp / "fig", tmp / "sw", tmp / "full", tmp / "afile"]
    return {"family": "cli", "input": " ".join(_short(a) for a in argv), "argv": argv,
            "outputs": outputs}  # fmt: skip


# -- public functions ----------------------------------------------------------------------
def api_case(rng: random.Random, tmp: Path) -> dict[str, Any]:
    """A public function of ``tests/test_api_hardening.py``'s table with one or two of its
    arguments replaced by a value of the same classes, judged by that file's contract."""
    import numpy as np

    sys.path.insert(0, str(Path(__file__).parent))
    import test_api_hardening as api

    name, func, base, extra, inf_ok = rng.choice(api.SPECS)
    draws = np.random.default_rng(rng.getrandbits(32))
    kwargs = dict(base)
    labels = []
    for key in rng.sample(list(base), min(len(base), rng.choice([1, 1, 2]))):
        pool = api._mutations(base[key], draws)
        kwargs[key] = pool[int(draws.integers(len(pool)))]
        labels.append(api._label(key, kwargs[key]))
    label = ", ".join(labels)
    return {"family": "api", "input": f"{name}({label})",
            "call": lambda: api.check_call(name, func, kwargs, extra, inf_ok, label)}  # fmt: skip


FAMILIES = {"scenario": scenario_case, "campaign": campaign_case, "cli": cli_case, "api": api_case}


def run_one(family: str, seed: int, index: int) -> dict[str, Any]:
    """Case ``index`` of ``family`` (its draws depend on the seed, the family and the index
    only), run and judged in this process."""
    rng = random.Random(f"{seed}:{family}:{index}")
    tmp = Path(tempfile.mkdtemp(prefix="crlbswarm-fuzz-"))
    start = time.perf_counter()
    problem = None
    case: dict[str, Any] = {"family": family, "input": "?"}
    try:
        case = FAMILIES[family](rng, tmp)
        if "call" in case:
            case.pop("call")()  # raises (pytest's Failed, or another exception) if broken
        else:
            outputs = case["outputs"]
            before = _snapshot(outputs)
            status, stdout, stderr = _run_cli(case["argv"])
            after = _snapshot(outputs)
            problem = judge_cli(status, stdout, stderr, before, after, outputs)
            case["stderr"] = stderr[-300:]
    except MemoryError:
        problem = "MemoryError"
    except BaseException as exc:  # the CLI must catch everything itself
        problem = f"uncaught {type(exc).__name__}: {str(exc)[:200]}"
        case["traceback"] = traceback.format_exc()[-800:]
    seconds = time.perf_counter() - start
    if problem is None and seconds > CASE_SECONDS:
        problem = "slow"
    shutil.rmtree(tmp, ignore_errors=True)
    case.pop("argv", None)
    case.pop("outputs", None)
    case.update(problem=problem, seconds=round(seconds, 2), index=index)
    return case


def _worker(seed: int) -> None:
    """Serve cases read from stdin (``family index`` per line), one JSON line each."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))
    for name in ("paper", "paper_safe", "sensing", "moving_target"):  # load the kernels
        _run_cli(["simulate", name, "--out", tempfile.mkdtemp() + "/warm"])
    print("ready", flush=True)
    for line in sys.stdin:
        family, index = line.split()
        print(json.dumps(run_one(family, seed, int(index)), default=str), flush=True)


class _Worker:
    """A worker process; restarted after a case that hangs or kills it."""

    def __init__(self, seed: int) -> None:
        env = {k: v for k, v in os.environ.items() if k != "CRLBSWARM_DEBUG"}
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--worker", "--seed", str(seed)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            text=True, env=env,
        )  # fmt: skip
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.proc.stdout, selectors.EVENT_READ)  # type: ignore[arg-type]
        if self._line(120) != "ready":
            raise RuntimeError("the fuzzing worker did not start")

    def _line(self, timeout: float) -> str | None:
        if not self.selector.select(timeout):
            return None
        line = self.proc.stdout.readline()  # type: ignore[union-attr]
        return line.strip() if line else None

    def run(self, family: str, index: int) -> dict[str, Any] | None:
        """The judged case, or None if it did not answer in time or the worker died."""
        self.proc.stdin.write(f"{family} {index}\n")  # type: ignore[union-attr]
        self.proc.stdin.flush()  # type: ignore[union-attr]
        line = self._line(2 * CASE_SECONDS)
        return json.loads(line) if line else None

    def close(self) -> int | None:
        self.proc.kill()
        return self.proc.wait()


def run(cases: int, seed: int, families: list[str], verbose: bool = False) -> list[dict[str, Any]]:
    """Run ``cases`` cases spread over ``families`` in a worker process; return the
    failures (a case that hangs or kills the worker is one)."""
    failures = []
    worker = _Worker(seed)
    try:
        for i in range(cases):
            family = families[i % len(families)]
            result = worker.run(family, i)
            if result is None:
                alive = worker.proc.poll() is None
                status = worker.close()
                problem = "hang" if alive else f"worker died (status {status})"
                result = {"family": family, "index": i, "problem": problem,
                          "input": _describe(family, seed, i)}  # fmt: skip
                worker = _Worker(seed)
            if result["problem"] is not None:
                failures.append(result)
                print(json.dumps(result, default=str), flush=True)
            elif verbose:
                print(f"ok {i} {family} {result['input'][:100]} ({result['seconds']} s)",
                      flush=True)  # fmt: skip
    finally:
        worker.close()
    return failures


def _describe(family: str, seed: int, index: int) -> str:
    """The input of a case, drawn again without running it."""
    tmp = Path(tempfile.mkdtemp(prefix="crlbswarm-fuzz-"))
    try:
        return str(FAMILIES[family](random.Random(f"{seed}:{family}:{index}"), tmp)["input"])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--family", action="append", choices=list(FAMILIES))
    parser.add_argument("--verbose", action="store_true")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        _worker(args.seed)
        return 0
    families = args.family or list(FAMILIES)
    failures = run(args.cases, args.seed, families, args.verbose)
    print(json.dumps({"cases": args.cases, "failures": len(failures)}))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
