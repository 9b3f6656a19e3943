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
