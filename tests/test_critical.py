"""Critical speeds (onset of parametric instability, of buckling) and stability maps.

The references are computed here, independently of the search: the verdict of a
plain ``kf.solve`` (or the sign of a plain ``kf.natural_frequencies``) just below and
just above the speed found. The 0.5 % acceptance against a fine scan at the default
tolerance is ``benchmarks/stability_map.py`` (``benchmarks/results/stability_map.md``).
"""

import csv
import dataclasses
import math
import warnings

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem import catalogue
from kedfem.analysis.critical import CriticalSpeed, critical_speed, itp_root
from kedfem.io.design_plots import StabilityMap, stability_map

RPM = 2 * math.pi / 60
LINEAR = ("inertia", "coupling", "axial_stiffening")


def verdict(scene, rpm):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kf.solve(dataclasses.replace(scene, speed=rpm * RPM)).stability.verdict


@pytest.mark.parametrize("scene, lo, hi", [
    ({"mechanism": {"name": "slider_crank"}, "accuracy": "fast"}, 4800.0, 5400.0),
    ({"mechanism": {"name": "four_bar", "elements": 2}, "accuracy": "fast"}, 570.0, 600.0)])
def test_parametric_onset_is_bracketed_by_the_verdicts_of_plain_solves(scene, lo, hi):
    """Preset scenes (the four-bar's geometric non-linearity linearised away; 2 elements per link to keep
    the test short) at rtol 1e-2: the onset to 5e-3 in fewer than 15 solves, a plain solve stable 5e-3
    below it and unstable 5e-3 above."""
    res = critical_speed(scene, lo * RPM, hi * RPM, linear=True)
    assert isinstance(res, CriticalSpeed) and res.kind == "parametric" and res.direction == "onset"
    assert res.met and res.solves < 15 and res.solves == len(res.evaluations)
    assert res.bracket[0] <= res.speed <= res.bracket[1] and res.bracket[1] - res.bracket[0] <= 5e-3 * res.speed
    assert res.value_lo < 1 < res.value_hi and res.effects == LINEAR
    plain = dataclasses.replace(kf.scene_from_dict(scene), effects=LINEAR)
    assert verdict(plain, res.rpm * (1 - 5e-3)) == "stable"
    assert verdict(plain, res.rpm * (1 + 5e-3)) == "unstable"


def test_buckling_speed_of_the_slider_crank():
    """The lowest modal eigenvalue over the cycle crosses zero: positive 0.5 % below, negative above."""
    scene = catalogue.info("slider_crank").scene()
    res = critical_speed(scene, 3000 * RPM, 9000 * RPM, kind="buckling", rtol=1e-3)
    assert res.met and res.solves <= 10 and res.value_lo >= 0 > res.value_hi and res.direction == "onset"

    def lowest(rpm):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = scene.mech.with_speed(rpm * RPM)
            return np.min(kf.natural_frequencies(m, n_modes=1, effects=LINEAR, steps=72).frequencies)

    assert lowest(res.rpm * (1 - 1e-3)) > 0 > lowest(res.rpm * (1 + 1e-3))
    assert "buckling at" in res.describe()


def test_itp_never_needs_more_than_one_step_over_bisection():
    """On a step-like function (log rho flat, then a square root: a tongue's edge) and on a smooth one."""
    calls = []

    def tongue(x):
        calls.append(x)
        return -0.25 if x < 0.3 else -0.25 + 2.0 * math.sqrt(x - 0.3)

    a, b = itp_root(tongue, 0.0, 1.0, -0.25, tongue(1.0), 1e-3)
    calls.pop(0)
    root = 0.3 + (0.25 / 2.0) ** 2
    assert a <= root <= b and b - a <= 1e-3 and len(calls) <= math.ceil(math.log2(1e3)) + 1
    calls.clear()
    a, b = itp_root(lambda x: calls.append(x) or x ** 2 - 0.5, 0.0, 1.0, -0.5, 0.5, 1e-6)
    assert a <= math.sqrt(0.5) <= b and len(calls) < math.log2(1e6)  # faster than bisection


def test_critical_speed_input_errors():
    scene = catalogue.info("slider_crank").scene(accuracy="fast")
    with pytest.raises(kf.InputError, match="lo must be < hi, got lo = 600 rad/s"):
        critical_speed(scene, 600.0, 500.0)
    with pytest.raises(kf.InputError, match="lo must be a finite speed > 0"):
        critical_speed(scene, -1.0, 500.0)
    with pytest.raises(kf.InputError, match="rtol must be a number in"):
        critical_speed(scene, 100.0, 500.0, rtol=0.0)
    with pytest.raises(kf.InputError, match="leave no solve of max_solves = 14"):
        critical_speed(scene, 100.0, 500.0, scan=12)
    with pytest.raises(kf.InputError, match="kind must be one of parametric, buckling"):
        critical_speed(scene, 100.0, 500.0, kind="flutter")
    with pytest.raises(kf.InputError, match=r"no sign change in the bracket: spectral radius 0\.\d+ \+- .* at lo = "
                                            r"1000 rpm and 0\.\d+ \+- .* at hi = 2000 rpm, stable at both ends"):
        critical_speed({"mechanism": {"name": "slider_crank"}, "accuracy": "fast"}, 1000 * RPM, 2000 * RPM)
    with pytest.raises(kf.InputError, match="the scene is undamped"):
        critical_speed(dataclasses.replace(scene, damping=None), 1000 * RPM, 2000 * RPM)


def test_four_bar_coupler_stiffness_alone():
    """coupler_EI defaults to link_EI (0: the same mechanism as before); given, it stiffens the coupler only."""
    same = mechanisms.build("four_bar", coupler_EI=0.616)
    assert mechanisms.build("four_bar").links["coupler"].section == mechanisms.build("four_bar", link_EI=0.616,
                                                                                       coupler_EI=0.0).links[
        "coupler"].section
    base = mechanisms.build("four_bar")
    f0 = kf.natural_frequencies(base, effects=("coupling",)).frequencies
    np.testing.assert_array_equal(kf.natural_frequencies(same, effects=("coupling",)).frequencies, f0)
    stiff = mechanisms.build("four_bar", coupler_EI=1.232)
    assert stiff.links["coupler"].section.I == pytest.approx(2 * base.links["coupler"].section.I)
    assert stiff.links["follower"].section == base.links["follower"].section
    with pytest.raises(kf.InputError, match="coupler_EI"):
        kf.scene_from_dict({"mechanism": {"name": "four_bar", "coupler_EI": -1.0}})
    with pytest.raises(kf.InputError, match="coupler_EI must be a bending stiffness"):
        mechanisms.build("four_bar", coupler_EI=float("nan"))
    assert kf.scene_from_dict({"mechanism": {"name": "four_bar", "coupler_EI": 1.232}}).mech.links[
        "coupler"].section.I == stiff.links["coupler"].section.I


def test_stability_map_serial(tmp_path):
    """A 2 x 3 map (damping x speed) of the slider-crank around its onset: the spectral radii are those of
    plain solves, damping raises the onset, and the files are written."""
    base = {"mechanism": {"name": "slider_crank"}, "accuracy": "fast"}
    speeds = np.array([5150.0, 5250.0, 5350.0]) * RPM
    smap = stability_map(base, speeds, "damping.zeta", [0.01, 0.03], scheduler="serial", progress=False)
    assert isinstance(smap, StabilityMap) and smap.spectral_radius.shape == (2, 3) and not smap.failures
    direct = verdict(kf.scene_from_dict(dict(base, damping={"zeta": 0.03})), 5350.0)
    assert (direct == "stable") == bool(smap.stable[1, 2])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rho = kf.solve(kf.scene_from_dict(dict(base, damping={"zeta": 0.01}, speed_rpm=5250.0))).stability
    assert smap.spectral_radius[0, 1] == pytest.approx(rho.spectral_radius, rel=1e-12)
    on = smap.onsets()
    assert smap.speeds[0] < on[0] < on[1] <= smap.speeds[-1] or math.isnan(on[1])
    lo, hi = smap.onset_brackets()
    assert lo[0] < on[0] <= hi[0] and lo[0] in smap.speeds and hi[0] in smap.speeds
    assert np.all(smap.spectral_radius[0][smap.speeds <= lo[0]] < 1) and smap.spectral_radius[0][smap.speeds == hi[0]] >= 1
    rows = list(csv.DictReader(open(smap.to_csv(tmp_path / "map.csv"))))
    assert len(rows) == 6 and rows[0]["damping.zeta"] == "0.01" and rows[0]["ok"] == "True"
    png = smap.plot(tmp_path / "map.png", marks=[(on[0], 0.01, "onset")])
    assert png.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(kf.InputError, match="param must be a dotted scene key other than the speed"):
        stability_map(base, speeds, "speed_rpm", [1.0])
    with pytest.raises(kf.InputError, match="damping.zeta"):
        stability_map(base, speeds, "damping.zeta", [2.0], scheduler="serial")


def test_the_buckling_speed_names_the_link_euler_would():
    """The four-bar preset buckles where its follower's compression from the rigid kinetostatics
    reaches the pinned-pinned Euler load pi^2 E I / L^2 (forces in speed^2, no gravity: read at
    400 rpm and scaled), to 3 %; the critical speed names the follower (the coupler's ratio is
    lower) near the crank angle of its largest compression, and so does a Campbell diagram whose
    band of mode 1 reaches below 0 Hz, whose crossings there are marked as no resonance, and the
    instability warning of a solve above that speed (once per solve)."""
    from kedfem.analysis.campbell import campbell, scene_at
    scene = catalogue.info("four_bar").scene()
    rigid = dataclasses.replace(scene_at(scene, 400 * RPM, effects=LINEAR), steps=72, estimate=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(rigid, progress=False)
    loads, motion = res.loads(), res.motion
    h = loads.history("rigid")
    euler = {}
    for link, (j0, j1) in (("coupler", ("A", "B")), ("follower", ("O4", "B"))):
        e = np.asarray(motion.position(j1)) - np.asarray(motion.position(j0))
        e /= np.linalg.norm(e, axis=-1, keepdims=True)
        push0 = np.sum(h.force[:, loads.bearings.index((j0, link))] * e, axis=-1)   # into the link at j0
        push1 = -np.sum(h.force[:, loads.bearings.index((j1, link))] * e, axis=-1)  # and at j1
        comp = np.maximum(push0, push1)
        lk = scene.mech.links[link]
        ratio = comp.max() / (math.pi ** 2 * lk.material.E * lk.section.I / lk.length ** 2)
        euler[link] = (400.0 / math.sqrt(ratio), math.degrees(res.crank_angle[int(np.argmax(comp))]) % 360)
    assert euler["follower"][0] < euler["coupler"][0]
    crit = critical_speed(scene, 300 * RPM, 1000 * RPM, kind="buckling", rtol=1e-3)
    assert abs(crit.rpm / euler["follower"][0] - 1) < 0.03, (crit.rpm, euler)
    assert crit.buckled is not None and crit.buckled.link == "follower" and crit.buckled.frequency < 0
    assert abs((math.degrees(crit.buckled.crank_angle) - euler["follower"][1] + 180) % 360 - 180) <= 10
    assert "link 'follower' buckles" in crit.describe()
    camp = campbell(scene, np.array([400.0, 500.0, 600.0, 700.0]) * RPM, n_modes=1, harmonics=2,
                    effects=LINEAR, progress=False)
    assert camp.buckled.tolist() == [False, False, True, True]
    assert camp.buckled_ranges(1) == [(600 * RPM, 700 * RPM)]
    text = camp.describe()
    assert "mode 1 BUCKLES" in text and "link 'follower' buckles" in text
    for c, line in zip(camp.crossings, text.splitlines()[1:]):
        assert ("the mode buckles" in line) == (c.speed_hi >= 600 * RPM)
    # a solve above the buckling speed: one instability warning, which names the link
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kf.solve(dataclasses.replace(scene_at(scene, 600 * RPM, effects=LINEAR), steps=96), progress=False)
    said = [str(w.message) for w in caught if issubclass(w.category, kf.InstabilityWarning)]
    assert len(said) == 1 and "link 'follower' buckles" in said[0], said


@pytest.mark.parametrize("effects, says", [
    (("inertia", "coupling", "axial_stiffening"), "the linear response there is not what the linkage does"),
    (("inertia", "coupling", "geometric_nonlinearity"), "runs post-buckled there"),
])
def test_the_summarys_buckled_line_fits_a_linear_and_a_non_linear_scene(effects, says):
    """A new user's Watt six-bar at 2000 rpm, converged and Floquet-stable under geometric_nonlinearity,
    read that "the linear response there is not what the linkage does" beside a negative modal
    frequency (the tangent stiffness at the response, frozen in time), and did not know what to believe."""
    from kedfem.io.report import format_summary

    res = kf.solve(kf.Scene(mechanisms.build("four_bar"), effects=effects, steps=48, estimate=False))
    freqs = res.frequencies(2, nodes=list(range(0, res.n, 8)))
    assert not (freqs.modal < 0).any()  # below the buckling speed: no such line
    text = format_summary(res, freqs, res.peaks(), stages={}, files=[], out_dir=None, source="test", scene_time=0.0)
    assert "BUCKLED" not in text
    modal = freqs.modal.copy()
    modal[: modal.shape[0] // 2, 0] *= -1.0  # as above a buckling speed: half the cycle
    text = format_summary(res, dataclasses.replace(freqs, modal=modal), res.peaks(), stages={}, files=[],
                          out_dir=None, source="test", scene_time=0.0)
    line = next(x for x in text.splitlines() if "BUCKLED" in x)
    assert says in line and "50 % of the cycle" in line
    assert ("Floquet" in line) == ("geometric_nonlinearity" in effects)
