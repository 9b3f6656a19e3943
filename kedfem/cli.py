"""Command-line interface: ``kedfem run``, ``kedfem list``."""

from __future__ import annotations

import argparse
import sys
import time

from . import __version__


def _cmd_list(args) -> int:
    import mechanisms

    from .effects import EFFECTS
    print("mechanisms:", ", ".join(mechanisms.available()))
    print("effects:")
    for e in EFFECTS.values():
        print(f"  {e.name:24s} {e.adds}")
    return 0


def _cmd_run(args) -> int:
    import mechanisms

    from .kinematics import kinematics
    from .modal import natural_frequencies
    t0 = time.perf_counter()
    mech = mechanisms.build(args.mechanism)
    mo = kinematics(mech, steps=args.steps)
    f = natural_frequencies(mech, n_modes=4, effects=("coupling", "axial_stiffening"), steps=args.steps)
    dt = time.perf_counter() - t0
    print(f"kedfem {__version__}: {mech.name}, {args.steps} time nodes, period {mo.period:.6g} s")
    print(f"loop-closure residual {mo.residual:.2e} m")
    print("natural frequencies over the cycle [Hz] (min / max):")
    for k in range(f.frequencies.shape[1]):
        print(f"  mode {k + 1}: {f.frequencies[:, k].min():10.3f} / {f.frequencies[:, k].max():10.3f}")
    print(f"wall time {dt:.3f} s")
    return 0


def main(argv=None) -> int:
    """Entry point of the ``kedfem`` console script."""
    p = argparse.ArgumentParser(prog="kedfem", description="Kineto-ElastoDynamics of planar elastic linkages")
    p.add_argument("--version", action="version", version=f"kedfem {__version__}")
    sub = p.add_subparsers(dest="command")
    r = sub.add_parser("run", help="analyse a mechanism")
    r.add_argument("mechanism", nargs="?", default="slider_crank")
    r.add_argument("--steps", type=int, default=360)
    sub.add_parser("list", help="list mechanisms and effects")
    args = p.parse_args(argv)
    if args.command is None:
        args = p.parse_args(["run"] + list(argv or []))
    from .errors import KedError
    try:
        return {"run": _cmd_run, "list": _cmd_list}[args.command](args)
    except KedError as e:
        print(f"kedfem: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
