"""The accuracy-versus-cost study runs (quick mode) and shows what it claims."""

import csv
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import accuracy_cost  # noqa: E402


def test_quick_study_writes_tables_and_radau_converges_at_its_rate(tmp_path):
    accuracy_cost.main(["--quick", "--out", str(tmp_path)])
    for f in ("accuracy_cost.csv", "accuracy_cost.md", "accuracy_cost.png"):
        assert (tmp_path / f).stat().st_size > 0
    rows = list(csv.DictReader(open(tmp_path / "accuracy_cost.csv")))
    sc = {int(r["n"]): float(r["true_error"]) for r in rows
          if r["mechanism"] == "slider-crank" and r["setting"] == "radau3" and r["knob"] == "elements"}
    # Radau IIA (3 stages) converges at >= 3 on the peaks, and the reference is far below its errors
    assert math.log2(sc[24] / sc[96]) / 2 >= 3.0, sc
    assert float(rows[0]["ref_uncertainty"]) < 1e-8
    # a tolerance-driven solve meets its tolerance against the reference
    for r in rows:
        if r["knob"] == "tolerance":
            assert r["met"] == "True" and float(r["true_error"]) <= 1e-3, r
    md = (tmp_path / "accuracy_cost.md").read_text()
    assert "| four-bar | radau3 |" in md
