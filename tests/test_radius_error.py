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


def test_the_upper_bound_of_a_numerically_damped_spectral_radius_holds_the_true_one():
    """A new user's crank-rocker (not in the catalogue) at 450 rpm ends on 48 elements, whose
    numerical damping lowers its spectral radius by orders of magnitude (1.5e-5, the verdict clear
    without more): ``Stability.upper`` bounds the resolved radius (768 elements), which the
    computed one does not."""
    import sys
    import warnings
    from pathlib import Path

    import kedfem as kf
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from linkages import strip_crank_rocker
    m = strip_crank_rocker(450.0, coupler_h=0.006)
    kw = dict(effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.Scene(m, **kw))
        ref = kf.solve(kf.Scene(m, steps=768, estimate=False, **kw)).stability.spectral_radius
    st = res.stability
    assert st.verdict == "stable" and st.spectral_radius < 0.01 * ref  # lowered by orders of magnitude
    assert ref <= st.upper <= 2.0 * ref  # measured: 2.31e-2 <= 2.98e-2
    assert st.radius_text() == f"below {st.upper:.1e}"
