"""The long run of the API and CLI fuzzer (issue 23): many examples, every distinct failure listed.

The suite runs a few hundred examples (tests/test_fuzz_api.py); this draws many more, without
stopping at the first failure, and prints each distinct violation once (the call, the exception
and its message), then a count per kind of outcome. Exit status 1 if anything failed.

    python benchmarks/fuzz_api.py                   # 3000 builder programs, 3000 calls, 200 CLI runs
    python benchmarks/fuzz_api.py --builder 500 --functions 500 --cli 50 --seed 7
"""

from __future__ import annotations

import argparse
import collections
import random
import sys
import time
import traceback
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from fuzz_api_cases import cli_argv, function_call, program, run_cli, run_function, run_program  # noqa: E402


def drive(label: str, strategy, run, n: int, seed: int, failures: dict, outcomes: collections.Counter) -> float:
    """Run ``n`` examples of ``strategy`` through ``run``; record distinct failures."""
    t0 = time.perf_counter()

    @settings(max_examples=n, deadline=None, database=None, derandomize=False,
              suppress_health_check=list(HealthCheck), phases=["generate"])
    @given(strategy)
    def body(x):
        try:
            out = run(*x) if label == "functions" else run(x)
            outcomes[f"{label}: {out}" if label != "cli" else f"cli: exit {out}"] += 1
        except BaseException as e:  # noqa: BLE001 - record and go on
            if isinstance(e, KeyboardInterrupt):
                raise
            tb = traceback.extract_tb(e.__traceback__)
            where = next((f"{Path(f.filename).name}:{f.lineno}" for f in reversed(tb) if "kedfem" in f.filename),
                         "?")
            key = (label, type(e).__name__, where)
            if key not in failures:
                failures[key] = (repr(x)[:300], f"{type(e).__name__}: {str(e)[:300]}")
            outcomes[f"{label}: FAILED"] += 1

    random.seed(seed)
    body()
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--builder", type=int, default=3000)
    ap.add_argument("--functions", type=int, default=3000)
    ap.add_argument("--cli", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    failures: dict = {}
    outcomes: collections.Counter = collections.Counter()
    times = {}
    for label, strategy, run, n in (("builder", program(), run_program, a.builder),
                                    ("functions", function_call(), run_function, a.functions),
                                    ("cli", cli_argv(), run_cli, a.cli)):
        if n:
            times[label] = drive(label, strategy, run, n, a.seed, failures, outcomes)
    for (label, kind, where), (example, msg) in sorted(failures.items()):
        print(f"FAIL {label} {kind} at {where}\n  example: {example}\n  {msg}\n")
    print("outcomes:")
    for k, v in sorted(outcomes.items()):
        print(f"  {v:6d}  {k}")
    print("wall time [s]: " + ", ".join(f"{k} {v:.0f}" for k, v in times.items()))
    print(f"{len(failures)} distinct failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
