"""docs/modelling.md stays true: its python blocks run in order, in one namespace, as written.

The blocks assert the numbers and signs the page states (closed forms, sign conventions), so a
change of the code that breaks the reference breaks this test.
"""

import os
import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "modelling.md"


def _blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE)


def test_the_page_has_an_example_per_section():
    text = DOC.read_text()
    sections = re.split(r"^## ", text, flags=re.MULTILINE)[1:]
    assert len(sections) >= 17
    for sec in sections:
        title = sec.splitlines()[0]
        assert "```python" in sec, f"section {title!r} has no python example"


def test_every_python_block_runs_in_order(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.chdir(tmp_path)
    blocks = _blocks(DOC.read_text())
    assert len(blocks) >= 18
    ns: dict = {"__name__": "modelling_doc"}
    for i, code in enumerate(blocks, 1):
        try:
            exec(compile(code, f"{DOC.name}, python block {i}", "exec"), ns)
        except Exception as e:  # name the block, keep the traceback
            pytest.fail(f"docs/modelling.md python block {i} failed: {type(e).__name__}: {e}\n{code}")
    out = capsys.readouterr().out
    assert "all sign conventions hold" in out
    assert not os.listdir(tmp_path)  # the examples write no files
