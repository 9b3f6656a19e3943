"""Campbell diagrams: frequency bands over the cycle against the drive's harmonics, and the resonance flags."""

import csv
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import kedfem as kf
import mechanisms
from kedfem import catalogue
from kedfem.analysis.campbell import CampbellResult, campbell, crossings

RPM = 2 * math.pi / 60


def cantilever_tip_mass_spring(L, EI, rho_A, M, k):
    """First natural frequency [Hz] of a clamped Euler-Bernoulli beam with a tip mass and a transverse
    tip spring: the root of the 2x2 determinant of w''(L) = 0, EI w'''(L) = (k - M w^2) w(L)."""
    def det(beta):
        bl, w2 = beta * L, beta ** 4 * EI / rho_A
        ch, c, sh, s = math.cosh(bl), math.cos(bl), math.sinh(bl), math.sin(bl)
        q = k - M * w2
        return (ch + c) * (EI * beta ** 3 * (ch + c) - q * (sh - s)) - (sh + s) * (EI * beta ** 3 * (sh - s)
                                                                             - q * (ch - c))
    betas = np.linspace(0.05, 10.0, 4000) / L
    vals = np.array([det(b) for b in betas])
    i = int(np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0])
    beta = brentq(det, betas[i], betas[i + 1], xtol=1e-14)
    return beta ** 2 * math.sqrt(EI / rho_A) / (2 * math.pi)


def test_exciter_band_is_the_closed_form_cantilever_and_its_crossings_the_exact_speeds():
    """The exciter is time-invariant: its first band has zero width at the continuous beam's frequency
    (tip mass 0.5 kg, tip spring 2e4 N/m), and harmonic k crosses it exactly at 2 pi f1 / k."""
    p = catalogue.info("exciter").parameters
    EI = p["E"] * p["width"] * p["height"] ** 3 / 12
    f1 = cantilever_tip_mass_spring(p["length"], EI, p["rho"] * p["width"] * p["height"], p["tip_mass"],
                                    p["spring"])
    speeds = 2 * math.pi * np.linspace(4.0, 30.0, 6)
    res = campbell(catalogue.info("exciter").scene(), speeds, n_modes=2, harmonics=4)
    assert isinstance(res, CampbellResult) and res.bands.shape == (6, 2, 3) and res.method == "modal"
    np.testing.assert_allclose(res.bands[:, 0, :], f1, rtol=1e-5)  # 8 cubic elements: 4e-6
    mode1 = {c.harmonic: c for c in res.crossings if c.mode == 1}
    assert sorted(mode1) == [1, 2, 3, 4]
    for k, c in mode1.items():
        exact = 2 * math.pi * res.bands[0, 0, 1] / k  # where k f_c meets the band
        assert c.speed_lo == pytest.approx(exact, rel=1e-9) and c.speed_hi == pytest.approx(exact, rel=1e-9)
        assert c.speed_mean == pytest.approx(exact, rel=1e-9) and not (c.open_lo or c.open_hi)
        assert c.rpm_lo == pytest.approx(c.speed_lo * 60 / (2 * math.pi))


def test_slider_crank_rod_at_low_speed_is_the_pinned_pinned_beam():
    """At 10 rpm the rod's first band tops out at the pinned-pinned beam 9.8696 sqrt(EI / (m L^4)) (where
    the rod lies along the slider's axis) and the slider's mass lowers it elsewhere by < 0.05 %."""
    EI, m, L = 2e11 * 0.008 ** 4 / 12, 7870 * 0.008 ** 2, 0.30
    f_pp = 9.8696 * math.sqrt(EI / (m * L ** 4)) / (2 * math.pi)
    res = campbell(mechanisms.build("slider_crank"), [10 * RPM, 20 * RPM], n_modes=1, harmonics=1)
    lo, mean, hi = res.band(1)[0]
    assert hi == pytest.approx(f_pp, rel=1e-4) and (hi - lo) / hi < 5e-4 and lo <= mean <= hi
    assert res.crossings == ()


def test_modal_bands_equal_the_solved_frequencies():
    """The default (modal analysis on the rigid-body motion) against the frequencies of a periodic solve:
    the same numbers where the effects are linear (slider-crank), within 2 % of every band edge and 0.5 %
    of every band mean where the preset's geometric non-linearity stiffens by the response (four-bar)."""
    sc = catalogue.info("slider_crank").scene(accuracy="fast")
    speeds = [1000 * RPM, 1500 * RPM]
    modal = campbell(sc, speeds, n_modes=3, nodes=24)
    solved = campbell(sc, speeds, n_modes=3, nodes=24, method="solve")
    np.testing.assert_allclose(solved.bands, modal.bands, rtol=1e-10)
    assert modal.crossings == solved.crossings
    fb = catalogue.info("four_bar").scene(accuracy="fast")
    m4 = campbell(fb, [190 * RPM, 200 * RPM], n_modes=4, nodes=24)
    s4 = campbell(fb, [190 * RPM, 200 * RPM], n_modes=4, nodes=24, method="solve")
    assert m4.effects == ("inertia", "coupling", "axial_stiffening") and "geometric_nonlinearity" in s4.effects
    rel = np.abs(s4.bands / m4.bands - 1)
    assert rel[..., [0, 2]].max() < 0.02 and rel[..., 1].max() < 0.005, rel


def test_crossings_between_samples_and_across_them():
    """A harmonic line running through a band between two speeds is found with its exact range (bands and
    lines linear in between), one crossing across several speeds is one record, open ends are flagged."""
    speeds = 2 * math.pi * np.array([5.0, 20.0, 40.0, 60.0])
    bands = np.zeros((4, 2, 3))
    bands[:, 0] = [10.0, 11.0, 12.0]            # constant band 10..12 Hz
    bands[:, 1] = [[30.0, 45.0, 60.0]] * 4      # wide band 30..60 Hz
    out = crossings(speeds, bands, np.array([1, 2]))
    by = {(c.mode, c.harmonic): c for c in out}
    c = by[(1, 1)]                                # f_c from 10 to 12 Hz: inside the first segment only
    assert c.speed_lo == pytest.approx(2 * math.pi * 10) and c.speed_hi == pytest.approx(2 * math.pi * 12)
    assert c.speed_mean == pytest.approx(2 * math.pi * 11) and not (c.open_lo or c.open_hi)
    assert by[(1, 2)].speed_lo == pytest.approx(2 * math.pi * 5) and by[(1, 2)].open_lo  # 2 f_c = 10 at 5 Hz
    c = by[(2, 1)]                                # 30..60 Hz: across two segments, open at the top
    assert c.speed_lo == pytest.approx(2 * math.pi * 30) and c.speed_hi == pytest.approx(2 * math.pi * 60)
    assert c.open_hi and not c.open_lo and c.speed_mean == pytest.approx(2 * math.pi * 45)
    assert by[(2, 2)].speed_lo == pytest.approx(2 * math.pi * 15) and by[(2, 2)].speed_hi == pytest.approx(
        2 * math.pi * 30)
    assert len(out) == 4


def test_campbell_files(tmp_path):
    res = campbell(catalogue.info("exciter").scene(), 2 * math.pi * np.linspace(4.0, 30.0, 5), n_modes=2,
                   harmonics=3)
    bands = res.to_csv(tmp_path / "campbell.csv")
    rows = list(csv.DictReader(open(bands)))
    assert len(rows) == 10 and float(rows[0]["f_mean_Hz"]) == pytest.approx(res.bands[0, 0, 1])
    assert float(rows[1]["speed_rpm"]) == pytest.approx(res.rpm[0]) and rows[1]["mode"] == "2"
    cross = list(csv.DictReader(open(res.crossings_to_csv(tmp_path / "crossings.csv"))))
    assert len(cross) == len(res.crossings) and cross[0]["harmonic"] == str(res.crossings[0].harmonic)
    assert all("nan" not in v.lower() for r in rows + cross for v in r.values())
    png = res.plot(tmp_path / "campbell.png")
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    assert "mode 1 x harmonic 1" in res.describe()


def test_campbell_input_errors():
    m = mechanisms.build("slider_crank")
    with pytest.raises(kf.InputError, match="speeds_rad_s must be finite, > 0 and strictly increasing"):
        campbell(m, [100.0, 50.0])
    with pytest.raises(kf.InputError, match="speeds_rad_s must be a 1-D sequence of at least 2"):
        campbell(m, [100.0])
    with pytest.raises(kf.InputError, match="n_modes must be an integer >= 1"):
        campbell(m, [50.0, 100.0], n_modes=0)
    with pytest.raises(kf.InputError, match="nodes must be an integer >= 3"):
        campbell(m, [50.0, 100.0], nodes=2)
    with pytest.raises(kf.InputError, match="method must be one of modal, solve"):
        campbell(m, [50.0, 100.0], method="fft")
    with pytest.raises(kf.InputError, match="scene must be a kf.Scene"):
        campbell("slider_crank", [50.0, 100.0])
