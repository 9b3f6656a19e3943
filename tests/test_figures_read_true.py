"""Printed figures carry no more digits than their error allows (issue: "numbers that read true")."""

import re

import pytest

from kedfem.analysis.results import Stability


@pytest.mark.parametrize("st, printed, absent", [
    # a clear verdict from a radius the numerical damping lowered by orders of magnitude
    (Stability(6.07628e-57, 2.1e-01, "stable", "radau3", 96), "below 2.1e-01", "6.07628e-57"),
    # an undamped scene: 1 by structure, the computed value named as the scheme's damping
    (Stability(1.19e-43, 1.07e-30, "marginal", "radau3", 96, "undamped", conservative=True),
     "1 by structure", "+-"),
    # a resolved radius: its digits down to its error's
    (Stability(0.258863123, 4.9e-05, "stable", "radau3", 192), "0.25886 +- 5e-05", "0.258863"),
    (Stability(0.5, None, "stable", "radau3", 48), "0.5 (no error estimate)", "+-"),
])
def test_spectral_radius_digits(st, printed, absent):
    line = st.describe()
    assert printed in line and absent not in line


def test_digits_never_exceed_the_error():
    for rho, err in [(0.123456789, 1e-3), (0.987654321, 2e-7), (3.4567e-3, 1e-5), (1.0000012, 1e-6)]:
        text = Stability(rho, err, "stable", "radau3", 96).radius_text()
        mant = re.match(r"([0-9.]+)", text).group(1)
        last = len(mant.split(".")[1]) if "." in mant else 0
        assert 10.0 ** -last >= err / 10 - 1e-18, (rho, err, text)  # the last digit is not below err / 10
        assert abs(float(mant) - rho) <= err, (rho, err, text)        # and the value is within its error


# --------------------------------------------------- the summaries of the catalogue, read back
import math  # noqa: E402

import numpy as np  # noqa: E402

import kedfem as kf  # noqa: E402
from kedfem import catalogue  # noqa: E402
from kedfem.io import scenefile as sf  # noqa: E402

NUMBER = r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?"


def _last_place(text: str) -> float:
    """The place value of a printed number's last digit (``"69.78"``: 0.01; ``"4.4e+04"``: 1000)."""
    mant, _, exp = text.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 10.0 ** (int(exp or 0) - decimals)


def _significant(text: str) -> int:
    mant = text.lower().partition("e")[0].lstrip("+-").replace(".", "").lstrip("0")
    return max(len(mant), 1)


def _reads_true(text: str, rel_err, what: str):
    """A printed figure's last digit is not below a tenth of its error; without one, three digits."""
    value = abs(float(text))
    if value == 0.0:
        return
    if rel_err is None:
        assert _significant(text) <= 3, (what, text, "no error estimate: at most three digits")
    else:
        assert _last_place(text) >= rel_err * value / 10 * (1 - 1e-9) or _significant(text) == 1, \
            (what, text, rel_err)


def check_summary(text: str) -> int:
    """Every peak, load and fatigue figure of a summary against the errors it prints; returns how
    many figures were read."""
    lines = text.splitlines()
    m = re.search(r"histories (" + NUMBER + ")", text)
    history = float(m.group(1)) if m else None
    read = 0
    start = next(i for i, s in enumerate(lines) if s.startswith("peak response"))
    for row in lines[start + 2:]:
        if row.strip().startswith("("):
            break
        tok = row.split()
        defl, de, stress, se = tok[1], tok[2], tok[4], tok[5]
        _reads_true(defl, None if de == "-" else float(de), f"{tok[0]} deflection")
        if stress != "n/a":
            _reads_true(stress, None if se == "-" else float(se), f"{tok[0]} stress")
        read += 2
    for row in lines:
        if row.strip().startswith(("bearing ", "drive ")):
            for num in re.findall(r"(?:peak|rms|\[)\s*(" + NUMBER + ")", row):
                _reads_true(num, history, row.strip()[:30])
                read += 1
        if "largest range" in row:
            for num in re.findall(r"(" + NUMBER + ") MPa", row):
                _reads_true(num, history, row.strip()[:30])
                read += 1
    floquet = next(s for s in lines if s.startswith("Floquet stability"))
    m = re.search(r"spectral radius (" + NUMBER + r") \+- (" + NUMBER + ")", floquet)
    if m:  # a resolved radius: digits down to its error
        assert _last_place(m.group(1)) >= float(m.group(2)) / 10 * (1 - 1e-9), floquet
    else:
        assert re.search(r"below " + NUMBER + r"|1 by structure|no error estimate", floquet), floquet
    return read


FAST_PRESETS = [k for k in catalogue.available() if k != "whitworth"]  # its preset solve takes 17 s


@pytest.mark.parametrize("key", FAST_PRESETS)
def test_catalogue_summaries_read_true(key):
    spec = sf.parse_scene({"mechanism": {"name": key}}, source="test")
    res = kf.solve(spec.scene, progress=False)
    assert check_summary(res.summary()) >= 4


@pytest.mark.parametrize("key", ["slider_crank", "four_bar"])
def test_undamped_summaries_read_true(key):
    spec = sf.parse_scene({"mechanism": {"name": key}, "damping": "none"}, source="test")
    assert spec.scene.damping is None
    res = kf.solve(spec.scene, progress=False)
    text = res.summary()
    assert check_summary(text) >= 4 and "1 by structure" in text


def test_the_whitworth_summary_reads_true():
    """The Whitworth on 192 fixed elements (no estimate: three digits) and the check's own rule."""
    res = kf.solve(kf.Scene(catalogue.build("whitworth"), steps=192, estimate=False), progress=False)
    assert check_summary(res.summary()) >= 4
    with pytest.raises(AssertionError):
        _reads_true("69.777", 1.2e-3, "five digits of a value known to 1.2e-3")
    with pytest.raises(AssertionError):
        _reads_true("1.0593", None, "four digits without an estimate")
