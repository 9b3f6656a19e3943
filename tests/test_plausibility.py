"""Results that leave the model's theory say so; a 'redundant' link that is not is an error."""

import dataclasses
import warnings

import pytest

import kedfem as kf
import mechanisms
from kedfem.analysis import plausibility


def test_a_kinematic_false_link_that_stretches_is_an_error_naming_it():
    """It used to solve and report a stress of 77 GPa."""
    m = mechanisms.build("four_bar", elements=2)
    coupler = m.links["coupler"]
    # a diagonal O2-B whose length changes with the crank angle: not a redundant member
    m.link("diagonal", "O2", "B", material=coupler.material, section=coupler.section, elements=2,
           kinematic=False)
    with pytest.raises(kf.InputError, match=r"link 'diagonal' is kinematic=False .*\(strain 0\.4"):
        kf.solve(kf.Scene(m, effects=("inertia", "coupling"), damping=kf.ModalDamping(0.02), steps=24))


def test_a_unit_slip_warns_of_large_deflection_and_yield():
    """E 1000x too small (MPa taken for GPa): the exciter's cantilever bends by a quarter of its
    length, far beyond small-deflection theory."""
    soft = mechanisms.build("exciter", E=2.0e8, eccentricity=0.04)
    with pytest.warns(kf.PlausibilityWarning, match=r"link 'beam': peak deflection .* % of its length.*"
                      r"small-deflection \(linear\) theory .* add geometric_nonlinearity"):
        res = kf.solve(kf.Scene(soft, effects=("inertia", "coupling", "springs"), damping=kf.ModalDamping(0.02),
                                steps=48))
    # with geometric_nonlinearity on, the warning speaks of its own (von Karman) theory, not of
    # small deflections (a new user's crank-rocker at 7-29 % of its coupler's length)
    gn = dataclasses.replace(res, scene=dataclasses.replace(res.scene, effects=res.scene.effects
                                                            + ("geometric_nonlinearity",)))
    with pytest.warns(kf.PlausibilityWarning) as caught:
        msgs = plausibility.check_result(gn)
    assert msgs and all("von Karman" in m and "small-deflection" not in m for m in msgs), msgs
    assert len(caught) == len(msgs)
    m = mechanisms.build("four_bar", elements=2)
    lk = m.links["coupler"]
    weak = kf.Material(E=lk.material.E, rho=lk.material.rho, yield_strength=1e6)  # 1 MPa
    m.links["coupler"] = type(lk)(**{**lk.__dict__, "material": weak})
    with pytest.warns(kf.PlausibilityWarning, match="exceeds the yield strength 1 MPa"):
        kf.solve(kf.Scene(m, effects=("inertia", "coupling"), damping=kf.ModalDamping(0.02), steps=48))


def test_a_plausible_result_is_quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("error", kf.PlausibilityWarning)
        kf.solve(kf.Scene(mechanisms.build("four_bar", elements=2), effects=("inertia", "coupling"),
                          damping=kf.ModalDamping(0.02), steps=48))
