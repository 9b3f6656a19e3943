"""Accuracy versus cost of every solver knob (slider-crank, four-bar, mould oscillator).

Run from the repository root::

    python benchmarks/accuracy_cost.py            # full study (~15-25 min on 2 cores)
    python benchmarks/accuracy_cost.py --quick    # smoke run (~15 s)

Same as ``kedfem bench``. Writes ``benchmarks/results/accuracy_cost.csv`` and
``accuracy_cost.md`` (the tables quoted in the README) and the Pareto plot
``docs/img/accuracy_cost.png`` (``--out DIR`` writes all three to ``DIR``).
What is measured and how the references are built: :mod:`kedfem.bench`.
"""

import os
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

from kedfem.bench import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(default_out=os.path.join(ROOT, "benchmarks", "results"),
                  default_plot=os.path.join(ROOT, "docs", "img", "accuracy_cost.png")))
