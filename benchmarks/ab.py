"""A/B timing of two source trees of kedfem on the same host, interleaved (machines are noisy).

Each round runs one fresh process per tree (alternating which goes first), each solving the case
once to warm up and then ``--repeats`` times, and keeps the process's best time; the script prints
every process's time, the median per tree and the ratio of the medians (second tree / first).

Cases: ``sc:NAME`` (the scene file ``examples/scenes/NAME.toml`` of each tree), ``default`` (the
default scene), ``slider:RTOL`` (the peers' slider-crank, 8 rod elements, the linear effects, 2 %
modal damping, radau3, tolerance-driven at RTOL).

Run, e.g. against the code of an earlier commit::

    git worktree add /tmp/base <commit>
    OPENBLAS_NUM_THREADS=1 python benchmarks/ab.py sc:four_bar /tmp/base . --rounds 4
    git worktree remove --force /tmp/base
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = r'''
import sys, time, json, warnings
sys.path.insert(0, TREE)
import os; os.chdir(TREE)
warnings.simplefilter("ignore")
import kedfem as kf

def make(case):
    if case.startswith("sc:"):
        return kf.load_scene(f"{TREE}/examples/scenes/{case[3:]}.toml")[0]
    if case == "default":
        return kf.default_scene()
    if case.startswith("slider:"):
        from mechanisms import slider_crank
        m = slider_crank.build(elements=8)
        return kf.Scene(m, effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02),
                        method="radau3", rtol=float(case[7:]))
    raise SystemExit(f"unknown case {case!r}")

sc = make(CASE)
kf.solve(sc, progress=False)
times = []
for _ in range(REPEATS):
    t = time.perf_counter()
    kf.solve(sc, progress=False)
    times.append(time.perf_counter() - t)
print(json.dumps(min(times)))
'''


def run(case: str, trees: list[str], rounds: int, repeats: int) -> dict[str, list[float]]:
    """Best time per process [s] of each tree, ``rounds`` processes each, interleaved."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"))
    out: dict[str, list[float]] = {t: [] for t in trees}
    for r in range(rounds):
        for tree in (trees if r % 2 == 0 else trees[::-1]):
            code = f"TREE = {os.path.abspath(tree)!r}\nCASE = {case!r}\nREPEATS = {repeats}\n" + CHILD
            p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
            if p.returncode:
                raise SystemExit(f"{tree}: {p.stderr[-2000:]}")
            out[tree].append(json.loads(p.stdout.strip().splitlines()[-1]))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("first", help="source tree A (the baseline)")
    ap.add_argument("second", help="source tree B")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args(argv)
    trees = [a.first, a.second]
    res = run(a.case, trees, a.rounds, a.repeats)
    for t in trees:
        print(f"{a.case:24s} {t:20s} median {1e3 * statistics.median(res[t]):8.1f} ms  "
              f"{[round(1e3 * x, 1) for x in res[t]]}")
    print(f"ratio {a.second} / {a.first} = {statistics.median(res[a.second]) / statistics.median(res[a.first]):.3f}")


if __name__ == "__main__":
    main()
