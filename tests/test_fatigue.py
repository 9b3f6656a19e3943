"""Stresses for fatigue: signed fibre stresses, the fatigue table, safety factors, the files."""

import csv
import math

import numpy as np
import pytest

import kedfem as kf
from kedfem.analysis.fatigue import fatigue_table, fibre_stress
from kedfem.io import scenefile as sf
from kedfem.io.fatigue_files import write_fatigue_csv, write_histories


@pytest.fixture(scope="module")
def slider_crank():
    return kf.solve(sf.scene_from_dict({"mechanism": {"name": "slider_crank"}}))


def test_histories_csv_at_mid_span_are_n_over_a_minus_plus_m_c_over_i(slider_crank, tmp_path):
    """The acceptance check: the signed top/bottom stress at mid-span in the CSV equals
    N/A -+ M c/I from the result's bending moment and axial force."""
    res = slider_crank
    link = "rod"
    write_histories(res, tmp_path / "h.csv")
    x = res.stations(link)
    mid = x[len(x) // 2]
    assert mid == pytest.approx(0.5 * res.model.mech.links[link].length)
    rows, units = {}, set()
    with open(tmp_path / "h.csv", newline="") as f:
        for r in csv.DictReader(f):
            units.add(r["unit"])
            if r["link"] == link and float(r["station_m"]) == pytest.approx(mid):
                rows.setdefault(r["quantity"], []).append(float(r["value"]))
    sec = res.model.mech.links[link].section
    M = res.bending_moment(link)[:, len(x) // 2]
    # the axial force at mid-span: the two elements meeting there, at their midpoints, carry the
    # distributed axial load; their mean is the force at the node to O(h^2)
    Ne = res.axial_force(link)
    k = len(x) // 2
    N_mid, _M = res.section_forces(link)
    N = N_mid[:, k]
    assert np.abs(N - 0.5 * (Ne[:, k - 1] + Ne[:, k])).max() < 0.05 * np.abs(Ne).max()
    assert units == {"Pa", "N", "N m", "m"}  # each row's SI unit in the unit column
    top, bottom = np.array(rows["stress_top"]), np.array(rows["stress_bottom"])
    scale = np.abs(bottom).max()
    np.testing.assert_allclose(top, N / sec.A - M * sec.c / sec.I, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(bottom, N / sec.A + M * sec.c / sec.I, rtol=0, atol=1e-8 * scale)
    # the unsigned stress the peaks use is the larger fibre's magnitude
    fs = fibre_stress(res, link)
    np.testing.assert_allclose(np.maximum(np.abs(fs.top), np.abs(fs.bottom)), res.stress(link),
                               rtol=1e-12, atol=1e-9 * scale)


def test_fatigue_table_means_alternating_and_safety_factors(slider_crank, tmp_path):
    res = slider_crank
    fs = fibre_stress(res, "rod", 4)  # the table's stations: 4 per element
    lf = fatigue_table(res).link("rod")
    assert lf.stations.size == res.stations("rod", 4).size
    both = np.stack([fs.top, fs.bottom], axis=-1)
    np.testing.assert_allclose(lf.mean, 0.5 * (both.max(0) + both.min(0)))
    np.testing.assert_allclose(lf.alternating, 0.5 * (both.max(0) - both.min(0)))
    assert lf.largest_range == pytest.approx(float((both.max(0) - both.min(0)).max()))
    assert lf.safety_yield is None  # the preset's material states no strength
    # the range between the nodes is not missed (the node-only table was 1 % low in a trial)
    nodes = fibre_stress(res, "rod", 1)
    assert lf.largest_range >= float(np.ptp(np.stack([nodes.top, nodes.bottom], -1), axis=0).max())
    # a material with strengths: Goodman and Soderberg at the worst station by hand
    Sy, Sut, Se = 250e6, 400e6, 160e6
    mat = kf.Material(E=2.0e11, rho=7800.0, yield_strength=Sy, ultimate_strength=Sut, endurance_limit=Se)
    from kedfem.analysis.fatigue import _link_fatigue
    lf2 = _link_fatigue(fs, mat)
    sa, sm = lf2.alternating, lf2.mean
    goodman = 1.0 / np.max(sa / Se + np.maximum(sm, 0.0) / Sut)
    soderberg = 1.0 / np.max(sa / Se + np.maximum(sm, 0.0) / Sy)
    assert lf2.safety_goodman == pytest.approx(goodman) and lf2.safety_soderberg == pytest.approx(soderberg)
    assert lf2.safety_yield == pytest.approx(Sy / np.abs(both).max())
    assert lf2.safety_soderberg <= lf2.safety_goodman  # S_y < S_ut: Soderberg is the stricter line
    assert "Goodman" in lf2.describe() and "MPa" in lf2.describe()
    path = write_fatigue_csv(fatigue_table(res), tmp_path / "f.csv")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * res.stations("rod", 4).size
    worst = max(rows, key=lambda r: float(r["alternating_Pa"]))
    assert float(worst["station_m"]) == pytest.approx(lf.worst_station) and worst["fibre"] == lf.worst_fibre


def test_material_strengths_are_checked():
    with pytest.raises(kf.InputError, match="yield_strength .* exceeds ultimate_strength"):
        kf.Material(E=2e11, rho=7800, yield_strength=500e6, ultimate_strength=400e6)
    with pytest.raises(kf.InputError, match="endurance_limit"):
        kf.Material(E=2e11, rho=7800, endurance_limit=-1.0)
    assert math.isclose(kf.Material(E=2e11, rho=7800, endurance_limit=1.5e8).endurance_limit, 1.5e8)


def test_npz_histories_without_csv(slider_crank, tmp_path):
    """kedfem run --no-csv stopped on a None path (a review found it)."""
    rep = slider_crank.write(tmp_path / "o", csv=False, vtk=False, plots=False, mesh_check=False)
    names = sorted(p.name for p in rep.files)
    assert names == ["histories.npz", "result.npz", "summary.txt"]
    z = np.load(tmp_path / "o" / "histories.npz")
    np.testing.assert_allclose(z["rod/stress_top_Pa"], fibre_stress(slider_crank, "rod").top)


def test_a_safety_factor_another_fibre_governs_is_described_with_that_fibres_stresses():
    """A new user's Watt six-bar: the line gave the largest range's fibre (bottom, mean -19.58 MPa,
    alternating 46.57 MPa) beside "Goodman 3.58", which that fibre gives as 180 / 46.57 = 3.87; the
    other fibre's tensile mean governed. The line now names the fibre and station each factor
    comes from, whose numbers reproduce it."""
    import re

    from kedfem.analysis.fatigue import FibreStress, _link_fatigue

    phase = np.linspace(0.0, 2 * np.pi, 73)[:-1, None]
    # station 0: top fibre -20 +- 46.57 MPa (the largest range), bottom fibre +19 +- 43.6 MPa
    top = np.hstack([-20e6 + 46.57e6 * np.sin(phase), 5e6 * np.sin(phase)])
    bottom = np.hstack([19e6 + 43.6e6 * np.sin(phase), 4e6 * np.sin(phase)])
    fs = FibreStress("coupler", np.array([0.0, 0.1]), phase[:, 0], top, bottom, top, top)
    steel = kf.Material(E=2.1e11, rho=7850.0, yield_strength=350e6, ultimate_strength=420e6,
                        endurance_limit=180e6)
    lf = _link_fatigue(fs, steel)
    assert lf.worst_fibre == "top" and lf.governing["Goodman"] == (0, 1)
    assert lf.safety_goodman == pytest.approx(1.0 / (43.6 / 180 + 19 / 420), rel=1e-3)
    text = lf.describe()
    m = re.search(r"Goodman ([\d.]+) \(at 0\.0 mm, bottom fibre: mean ([\d.]+) MPa, alternating ([\d.]+) MPa\)", text)
    assert m, text
    n, mean, alt = (float(x) for x in m.groups())
    assert n == pytest.approx(1.0 / (alt / 180 + mean / 420), rel=2e-3)  # the numbers shown give it
    assert "top fibre: mean -20" in text  # the largest range as before
