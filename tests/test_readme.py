"""The README starts with the two fresh-machine commands and CI runs the second."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_readme_commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    block = lines[lines.index("```bash") + 1: lines.index("```bash") + 3]
    assert block[0].startswith("python3 -m venv .venv") and block[0].endswith("kedfem run")
    assert block[1].startswith("python3 -m venv .venv") and "pytest" in block[1]
    assert "[test]" in block[1]
    ci = (ROOT / ".ci" / "run").read_text()
    assert "README.md" in ci and "sed -n 2p" in ci


def test_readme_example_runs_and_prints_a_converged_stress(capsys):
    """The README's Python block runs as shown and its printed stress is right to its tolerance.

    Truth: the same scene by Gauss-Legendre collocation (a second method) on 8x the elements.
    """
    import re

    import kedfem as kf

    text = (ROOT / "README.md").read_text()
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)
    out = capsys.readouterr().out
    m = re.search(r"([0-9.]+) MPa \+- ([0-9.e+-]+) (stable|unstable|marginal)", out)
    assert m, out
    scene = ns["scene"]
    import dataclasses
    ref = kf.solve(dataclasses.replace(scene, steps=8 * ns["res"].elements, method="gauss3",
                                       estimate=False)).peaks()[0].stress / 1e6
    assert abs(float(m.group(1)) - ref) <= max(1e-3 * ref, 0.005 + float(m.group(2)) * ref)
    assert m.group(3) == "stable"
