"""The highest ratio over Newmark that kedfem, as users run it, could reach (issue 25's peers' targets).

For the slider-crank of ``benchmarks/peers.py`` (24 DOFs, 2 % and 0.5 % modal damping, targets
1e-4 and 1e-6 on the rod's mid-span deflection), measured in one run on one BLAS thread:

* Newmark from rest at the fewest steps per cycle ``I_n`` that meet the target: its stepping time
  ``N_s`` (from assembled terms) and its assembly on its grid ``A_n`` (kinematics, FE model,
  ``M, C, K, Q`` at ``I_n`` instants, the modal damping field): end to end ``N_s + A_n``;
* kedfem as users run it (``rtol`` = target, its levels and estimate): end to end, its periodic
  solver's time over all levels ``K_s``, and the instants its levels assemble at ``I_k``
  (3 Radau stages per element of every level).

Both take ``M, C, K, Q`` from the same assembler (the same modal damping field), so an instant costs
both the same. Whatever that cost, and whatever the rest of kedfem's bookkeeping costs (at least
nothing), the ratio ``(N_s + c I_n) / (K_s + c I_k)`` is at most ``max(N_s / K_s, I_n / I_k)``:
the *ceiling* printed. A second ceiling keeps today's assembly price (``c = A_n / I_n``) and makes
everything else of kedfem free. The last two columns are the same ceilings for one solve on the
final level with an estimate that cost nothing. kedfem's solver times are the fastest of the repeats,
Newmark's the median (the ceilings lean towards kedfem).

Run (about 2 min)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/peers_ceiling.py
"""

from __future__ import annotations

import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import peers  # noqa: E402  the slider-crank study, Newmark from rest and the timing helpers
import kedfem as kf  # noqa: E402
from kedfem.solvers import schemes  # noqa: E402
from kedfem.solvers.threads import one_blas_thread  # noqa: E402

#: Issue 25's targets: (damping ratio, tolerance) -> Newmark / kedfem as users run it, end to end
TARGETS = {(0.02, 1e-4): 3.0, (0.02, 1e-6): 30.0, (0.005, 1e-4): 5.0, (0.005, 1e-6): 50.0}
#: Newmark's steps per cycle tried, as in peers.py
LADDER = [peers.NE * k for k in (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 48, 64, 96, 128)]


def median_time(fn, repeats):
    """Median wall time of ``repeats`` calls and the last output (peers.py's, every call made)."""
    return peers._median_time(fn, repeats, long=math.inf)


def row(st, zeta, tol, repeats):
    """The measured ratio and the ceilings at one damping and tolerance."""
    stages = schemes.get("radau3").stages
    runs = []
    e2e_k, rt = median_time(lambda: runs.append(kf.solve(st.scene(rtol=tol))) or runs[-1], repeats)
    K_s = min(r.timings.solve for r in runs)  # kedfem's fastest: the ceiling is generous to it
    I_k = stages * sum(rt.error.levels)
    n_final = rt.elements
    one_s = min(kf.solve(st.scene(n_final)).timings.solve for _ in range(repeats))
    nm = next(n for n in LADDER
              if st.error(peers.direct_periodic(st.terms(n), st.T, st, "newmark", tol).U) <= tol)
    N_s, _ = median_time(lambda: peers.direct_periodic(st.terms(nm), st.T, st, "newmark", tol), repeats)
    A_n, _ = median_time(lambda: st.assemble(nm), repeats)
    c = A_n / nm
    e2e_n = N_s + A_n
    ceiling = max(N_s / K_s, nm / I_k)
    ceiling_asm = e2e_n / (K_s + c * I_k)
    free_est = max(N_s / one_s, nm / (stages * n_final))
    free_est_asm = e2e_n / (one_s + c * stages * n_final)
    return dict(zeta=zeta, tol=tol, target=TARGETS[(zeta, tol)], levels="/".join(map(str, rt.error.levels)),
                nm=nm, N_s=N_s, A_n=A_n, e2e_k=e2e_k, K_s=K_s, I_k=I_k, measured=e2e_n / e2e_k,
                ceiling=ceiling, ceiling_asm=ceiling_asm, free_est=free_est, free_est_asm=free_est_asm)


def main(repeats: int = 5):
    rows = []
    with one_blas_thread():
        for zeta in (0.02, 0.005):
            st = peers.SliderCrank(zeta, 1536)
            for tol in (1e-4, 1e-6):
                r = row(st, zeta, tol, repeats)
                rows.append(r)
                print(f"zeta {zeta}, target {tol:.0e}: measured {r['measured']:.1f}x, ceiling {r['ceiling']:.1f}x "
                      f"(target {r['target']:g}x)", flush=True)
    print("\n| damping | target | Newmark steps, stepping + assembly [s] | kedfem levels, end to end [s], "
          "solver [s], instants | measured | ceiling | ceiling at today's assembly | free estimate: "
          "ceiling / at today's assembly | issue 25 |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {100 * r['zeta']:g} % | {r['tol']:.0e} | {r['nm']}, {r['N_s']:.3f} + {r['A_n']:.3f} | "
              f"{r['levels']}, {r['e2e_k']:.3f}, {r['K_s']:.4f}, {r['I_k']} | {r['measured']:.1f}x | "
              f"{r['ceiling']:.1f}x | {r['ceiling_asm']:.1f}x | {r['free_est']:.1f}x / {r['free_est_asm']:.1f}x | "
              f"{r['target']:g}x |")


if __name__ == "__main__":
    main()
