"""Calibrate the mould oscillator's leaf-spring length so that group 1 gives the paper's 17.33 Hz.

Run: ``python benchmarks/calibrate_mould.py``. Prints the secant iterations and
the calibrated ``leaf_length``; the value is then the default in
``mechanisms/mould_oscillator.py`` (see its docstring).
"""

from __future__ import annotations

import warnings

from kedfem.analysis.defaults import default_scene
from kedfem.analysis.pipeline import solve

TARGET = 17.33  # Hz, paper Table 3, group 1, state-space method


def fundamental(leaf_length: float, steps: int = 180) -> float:
    res = solve(default_scene(group=1, steps=steps, leaf_length=leaf_length))
    if not res.converged:
        warnings.warn(f"not converged at leaf_length={leaf_length}")
    return res.frequencies(2).fundamental


def main():
    x0, x1 = 0.95, 1.0
    f0, f1 = fundamental(x0), fundamental(x1)
    for it in range(8):
        print(f"leaf_length {x1:.6f} m -> {f1:.5f} Hz")
        if abs(f1 - TARGET) < 1e-4:
            break
        x0, x1, f0 = x1, x1 + (TARGET - f1) * (x1 - x0) / (f1 - f0), f1
        f1 = fundamental(x1)
    print(f"calibrated leaf_length = {x1:.5f} m (group 1: {f1:.4f} Hz, target {TARGET} Hz)")


if __name__ == "__main__":
    main()
