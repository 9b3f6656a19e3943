"""The error of a result's spectral radius from its levels' radii (kedfem.analysis.stability_floor)."""


def test_a_spectral_radius_that_does_not_converge_gets_no_extrapolation_credit():
    """The radii of a parametrically unstable linkage near its change point on 3072/6144/12288
    elements (a new user's case) do not contract: the error is their last change, not that change
    over 2^rate - 1 (printed 1.5e+28 +- 2e+27 before). Contracting radii keep the credit."""
    from kedfem.analysis.stability_floor import radius_error
    assert radius_error([1.186e24, 4.018e28, 1.489e28], [3072, 6144, 12288], 3.1) == abs(1.489e28 - 4.018e28)
    assert radius_error([0.30, 0.26, 0.2589], [48, 96, 192], 4.0) == abs(0.2589 - 0.26) / 15.0
    assert radius_error([0.26, 0.2589], [96, 192], 4.0) == abs(0.2589 - 0.26) / 15.0
    assert radius_error([0.2589], [192], 4.0) is None
