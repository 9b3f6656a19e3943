"""The mesh-error estimate against mesh convergence (12 elements per link as the truth: its own
error is about (4/12)^4 = 1/81 of the 4-element mesh's)."""

import pytest

import kedfem as kf
import mechanisms
from kedfem.analysis.mesh_check import coarsened, comparison_mesh, mesh_error

LINEAR = ("inertia", "coupling", "axial_stiffening")


def _solve(name, elements):
    m = mechanisms.build(name, elements=elements)
    # time discretisation to 1e-4 (true errors ~1e-5): below the mesh errors of 1e-4 .. 6e-4 compared
    return kf.solve(kf.Scene(m, effects=LINEAR, damping=kf.ModalDamping(0.02), rtol=1e-4))


@pytest.mark.parametrize("name", ["slider_crank", "four_bar"])
def test_mesh_error_of_a_four_element_mesh_is_of_the_right_size(name, tmp_path):
    res = _solve(name, 4)
    est = mesh_error(res)
    truth = {p.link: p for p in _solve(name, 12).peaks()}
    assert est is not None and est.rate == 4.0
    checked = 0
    for p in res.peaks():
        e = est.link(p.link)
        assert (e.elements, e.comparison_elements) == (4, 2)
        for got, want, what in ((p.stress, truth[p.link].stress, "stress"),
                                (p.deflection, truth[p.link].deflection, "deflection")):
            true = abs(got / want - 1)
            assert true < 1e-3, (p.link, what, true)  # four elements per link: within 0.1 %
            if true > 1e-4:   # the errors the time discretisation (1e-5) does not blur
                estimate = e.stress if what == "stress" else e.deflection
                assert true / 3 <= estimate <= 10 * true, (p.link, what, estimate, true)
                checked += 1
    assert est.peak < 1e-3   # and it says so
    # and whether that is above the result's tolerance, in Python as on the command line
    assert est.rtol == 1e-4 and ("above the tolerance 1e-04" in est.describe()) == (est.peak > 1e-4)
    assert checked >= (3 if name == "four_bar" else 0)
    # the result's summary shows the check once made (a new user's read "mesh error: not estimated"),
    # and so does the folder written without a check of its own
    text = res.summary()
    assert "mesh error (not in the +- columns)" in text and "mesh error: not estimated" not in text
    if name == "slider_crank":
        rep = res.write(tmp_path, mesh_check=False, plots=False, vtk=False, render=False, modes=False)
        assert "mesh error (not in the +- columns)" in rep.summary and "mesh check off" not in rep.summary


def test_links_of_one_element_are_compared_with_two_and_the_mechanism_is_left_alone():
    """One cubic element per rod: its mid-span deflection is 20 % off; the check compares it with two
    elements (a coarser mesh does not exist) and says so, within a factor of two of the truth."""
    res = _solve("slider_crank", 1)
    est = mesh_error(res)
    e = est.link("rod")
    assert (e.elements, e.comparison_elements) == (1, 2)
    truth = _solve("slider_crank", 12).peaks()[0]
    p = res.peaks()[0]
    for got, want, estimate in ((p.deflection, truth.deflection, e.deflection), (p.stress, truth.stress, e.stress)):
        true = abs(got / want - 1)
        assert true / 2 <= estimate <= 2 * true, (estimate, true)
    m8 = mechanisms.build("slider_crank", elements=8)
    c = coarsened(m8)
    assert c.links["rod"].elements == 4 and m8.links["rod"].elements == 8
    assert comparison_mesh(mechanisms.build("slider_crank", elements=3)).links["rod"].elements == 6


def _welded_arm(elements):
    """A crank-rocker whose rocker carries a welded aluminium arm with a tip mass (a user's linkage,
    not in the catalogue): the links' axial forces vary along them under their own inertia."""
    import math
    import numpy as np
    O4, A = np.array([0.20, 0.0]), np.array([0.05, 0.0])
    d = O4 - A
    dist = float(np.hypot(*d))
    x = (0.22**2 - 0.16**2 + dist**2) / (2 * dist)
    B = A + x * d / dist + math.sqrt(0.22**2 - x**2) * np.array([-d[1], d[0]]) / dist
    m = kf.Mechanism("welded arm")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=tuple(O4))
    m.joint("A", at=tuple(A))
    m.joint("B", at=tuple(B), welded=("rocker", "arm"))
    m.joint("C", at=tuple(B + np.array([0.12, 0.05])))
    steel, sec = kf.Material(E=2.06e11, rho=7850.0), kf.Section.rectangle(0.020, 0.005)
    m.link("crank", "O2", "A", rigid=True, mass=0.3)
    m.link("coupler", "A", "B", material=steel, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=steel, section=sec, elements=elements)
    m.link("arm", "B", "C", material=kf.Material(E=7.0e10, rho=2700.0), section=kf.Section.rectangle(0.015, 0.004),
           elements=elements)
    m.point_mass("C", 0.2)
    m.drive("crank", speed=400 * 2 * math.pi / 60)
    return m


def test_axial_stiffening_keeps_the_cubic_elements_fourth_order_mesh_convergence():
    """The kinetostatic axial force varies along a link; the geometric stiffness of its element means
    made the deflections converge at rate 2 (2.0 on this linkage) and the recovered stresses on 4
    elements 4e-5 .. 1.2e-4 from 8 (now 2e-7 .. 2e-6), below the rate-4 mesh estimate's reach (0.2x
    the truth)."""
    import math
    peaks = {}
    for e in (2, 4, 8):
        res = kf.solve(kf.Scene(_welded_arm(e), effects=LINEAR, damping=kf.ModalDamping(0.02), steps=192,
                                method="radau3", estimate=False))
        peaks[e] = {p.link: p for p in res.peaks()}
    for link in peaks[2]:
        d = [peaks[e][link].deflection for e in (2, 4, 8)]
        rate = math.log2(abs(d[1] - d[0]) / abs(d[2] - d[1]))
        assert rate > 3.5, (link, rate)
        assert abs(peaks[4][link].stress / peaks[8][link].stress - 1) < 5e-6, link



def test_where_newton_fails_from_the_result_the_comparison_goes_up_its_levels_as_the_result_did(monkeypatch,
                                                                                               caplog):
    """The six-bar preset at 1600 rpm (past two folds of its response) solved in 80 s; its mesh check's
    Newton from the result failed on the comparison mesh, and the check ran a continuation in speed on
    all 1536 time elements (a Newton solve on them per step, 20 min; now 90 s). Where Newton from the result
    fails, the comparison now solves its levels from the coarsest that resolves the excited modes up,
    as the result's own solve did. Here the start is spoiled (100x the result) so that Newton fails from
    it: the estimate is the one the result's own start gives."""
    import logging

    from kedfem.analysis import mesh_check
    from kedfem.analysis.homotopy import Homotopy

    m = mechanisms.build("four_bar")
    res = kf.solve(kf.Scene(m, effects=LINEAR + ("geometric_nonlinearity",), damping=kf.ModalDamping(0.02),
                            steps=96, estimate=False))
    good = mesh_error(res)
    restricted = mesh_check._restricted_start

    def spoiled(*a):
        s = restricted(*a)
        d = s.sampler.discrete

        class Far:
            period = d.period

            def at(self, t):
                U, V = d.at(t)
                return 100.0 * U, 100.0 * V
        s.sampler.discrete = Far()
        return s

    runups = []
    homotopy = Homotopy.homotopy

    def watched(self, prob, *a, **k):
        runups.append(prob.n)
        return homotopy(self, prob, *a, **k)

    monkeypatch.setattr(mesh_check, "_restricted_start", spoiled)
    monkeypatch.setattr(Homotopy, "homotopy", watched)
    with caplog.at_level(logging.INFO, logger="kedfem"):
        est = mesh_error(res)
    text = " ".join(r.getMessage() for r in caplog.records)
    # the start failed, the levels ran, and the comparison's messages say whose they are (a new user
    # read its run-up warnings after the solve's as the solve starting over)
    assert "four-bar (mesh check: 4 -> 2 elements per link): Newton from the result did not converge on 96" in text
    assert "as the result's own solve did (it took" in text and res.model.mech.name == "four-bar"
    assert "level n=48" in text and all(n < 96 for n in runups)
    for a, b in zip(good.links, est.links):
        assert a.link == b.link and a.deflection == pytest.approx(b.deflection, rel=1e-3, abs=1e-9)
        assert a.stress == pytest.approx(b.stress, rel=1e-3, abs=1e-9)
