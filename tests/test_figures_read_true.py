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
