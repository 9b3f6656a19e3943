"""Every CSV table kedfem writes reads into pandas with typed columns and the one unit convention
(issue 27; docs/usage.md "Tables"): snake_case names, the SI unit as the name's suffix (``_m``,
``_Pa``, ``_Hz``, ``_rad_s``, ...), angles named ``_deg`` or ``_rad``, dimensionless and text
columns without one, and in the long tables a ``value`` column whose unit each row names in
``unit``."""

import dataclasses
import math
import re
import warnings

import numpy as np
import pandas as pd
import pytest

import kedfem as kf
import mechanisms
from kedfem import catalogue
from kedfem.analysis.accuracy import LinkError
from kedfem.analysis.continuation import Bifurcation, Branch, BranchPoint
from kedfem.io import sweep
from kedfem.io.design_plots import stability_map

#: the unit suffixes a column may end in (SI; rpm and degrees where a user reads them)
UNITS = ("m", "s", "Pa", "N", "N_m", "Hz", "rad", "deg", "rpm", "rad_s", "kg0.5_m")
#: the units a long table's ``unit`` column may name
ROW_UNITS = {"m", "Pa", "N", "N m", "rad"}
#: columns that are text, flags, counts or dimensionless numbers: no unit suffix
PLAIN = {"link", "fibre", "quantity", "value", "unit", "response", "joint", "member", "component", "point",
         "mode", "harmonic", "kind", "ok", "error", "stable", "converged", "iterations", "spectral_radius",
         "damping_ratio", "oscillating", "open_lo", "open_hi", "error_estimate_met", "periods",
         "multiplier_re", "multiplier_im", "stable_before", "stable_after", "worker", "damping.zeta",
         "deflection_time_error", "stress_time_error", "deflection_mesh_error", "stress_mesh_error"}
TEXT = {"link", "fibre", "quantity", "unit", "response", "joint", "member", "component", "kind", "error"}
#: words that make a column a physical quantity, and the suffixes its unit may take
QUANTITY = {"angle": ("rad", "deg"), "station": ("m",), "speed": ("rad_s", "rpm"), "stress": ("Pa",),
            "deflection": ("m",), "modal": ("Hz",), "state_space": ("Hz",), "frequency": ("Hz",), "f_": ("Hz",),
            "crank": ("Hz", "rad", "deg")}


def check_table(path, dof_labels=()):
    """Read ``path`` with pandas and check its columns against the convention; return the frame."""
    df = pd.read_csv(path, comment="#")
    assert len(df) > 0, path.name
    for col in df.columns:
        # snake_case (a DOF label may name its member: B.u[rocker]_m), no '[unit]' or spaces
        assert re.fullmatch(r"[A-Za-z0-9_.@]+(\[[A-Za-z0-9_]+\])?[A-Za-z0-9_.@]*", col) and not col.endswith("]"), \
            f"{path.name}: column {col!r} is not snake_case"
        stem = next((col[: -len(u) - 1] for u in sorted(UNITS, key=len, reverse=True) if col.endswith("_" + u)),
                    None)
        if stem is None:
            assert col in PLAIN, f"{path.name}: column {col!r} names no unit and is not a known plain column"
        else:
            unit = col[len(stem) + 1:]
            word = next((w for w in QUANTITY if w in stem), None)  # the first word named decides (an angle first)
            if word is not None:
                assert unit in QUANTITY[word], f"{path.name}: {col!r} in {unit}, a {word} wants {QUANTITY[word]}"
        if col in TEXT:
            continue
        # typed: numbers read as numbers, flags as booleans (an all-empty column reads as float NaN)
        kind = df[col].dtype.kind
        assert kind in "fiub", f"{path.name}: column {col!r} reads as {df[col].dtype}, not a number or flag"
    if "value" in df.columns:
        assert "unit" in df.columns and set(df["unit"]) <= ROW_UNITS, f"{path.name}: units {set(df['unit'])}"
        assert df["value"].dtype.kind == "f"
    for col in df.columns:
        if col.endswith("_deg"):
            assert df[col].between(0.0, 360.0).all(), f"{path.name}: {col} outside [0, 360)"
    return df


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A result's folder with every table of ``kedfem run`` (mesh check on)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.Scene(mechanisms.build("slider_crank", elements=4), steps=24,
                                effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02)))
        out = tmp_path_factory.mktemp("tables") / "run"
        res.write(out, plots=False, vtk=False, npz=False, mesh_check=True)
    return res, out


def test_the_result_folders_tables(folder):
    res, out = folder
    names = sorted(p.name for p in out.glob("*.csv"))
    assert names == ["fatigue.csv", "frequencies.csv", "histories.csv", "loads.csv", "peaks.csv", "response.csv"]
    for name in names:
        check_table(out / name)
    # the values are the result's, in the units the names say
    peaks = check_table(out / "peaks.csv")
    p = res.peaks()[0]
    row = peaks.set_index("link").loc[p.link]
    assert row["peak_stress_Pa"] == p.stress and row["deflection_angle_rad"] == p.deflection_angle
    assert np.isfinite(row["deflection_mesh_error"]) and np.isfinite(row["stress_time_error"])
    resp = check_table(out / "response.csv")
    np.testing.assert_array_equal(resp["t_s"].to_numpy(), res.t)
    assert [c for c in resp.columns[2:]] == [f"{d}_{'rad' if d.split('.')[-1].split('@')[0] in ('theta', 'phi') else 'm'}"
                                             for d in res.dof_labels]
    freqs = check_table(out / "frequencies.csv")
    assert freqs["oscillating"].dtype == bool and set(freqs["mode"]) == {1, 2, 3, 4}
    hist = check_table(out / "histories.csv")
    assert set(hist["quantity"]) == {"stress_top", "stress_bottom", "axial_force", "bending_moment", "deflection"}
    assert set(hist.loc[hist["quantity"] == "bending_moment", "unit"]) == {"N m"}
    loads = check_table(out / "loads.csv")
    assert set(loads.loc[loads["quantity"] == "bearing_force", "unit"]) == {"N"}
    fat = check_table(out / "fatigue.csv")
    assert (fat["alternating_Pa"] >= 0).all()


def test_the_design_studies_tables(tmp_path):
    camp = kf.campbell(catalogue.info("exciter").scene(), 2 * math.pi * np.linspace(4.0, 30.0, 5), n_modes=2,
                       harmonics=3)
    bands = check_table(camp.to_csv(tmp_path / "campbell.csv"))
    assert bands["speed_rpm"].to_numpy() == pytest.approx(np.repeat(camp.rpm, 2))
    cross = check_table(camp.crossings_to_csv(tmp_path / "campbell_crossings.csv"))
    assert cross["speed_lo_rpm"].to_numpy() == pytest.approx([c.rpm_lo for c in camp.crossings])
    assert cross["speed_at_mean_rad_s"].to_numpy() == pytest.approx([c.speed_mean for c in camp.crossings])
    base = {"mechanism": {"name": "slider_crank", "elements": 3}, "steps": 24,
            "effects": ["inertia", "coupling"], "damping": {"model": "modal", "zeta": 0.02}}
    res = sweep.run_sweep(base, {"speed_rpm": [500.0, 1000.0]}, scheduler="serial", progress=False)
    table = check_table(res.to_csv(tmp_path / "sweep.csv"))
    assert table["peak_stress_Pa"].dtype.kind == "f" and table["stable"].dtype == bool
    smap = stability_map({"mechanism": {"name": "slider_crank", "elements": 3}, "steps": 24},
                         np.array([500.0, 1000.0]) * kf.units.RAD_S_PER_RPM, "damping.zeta", [0.01, 0.03],
                         scheduler="serial", progress=False)
    check_table(smap.to_csv(tmp_path / "stability_map.csv"))
    # a failed point's radius and verdict are not computed: empty cells, not 'False'
    failed = dataclasses.replace(smap, spectral_radius=np.where([[True, False], [False, False]], np.nan,
                                                                smap.spectral_radius),
                                 stable=np.where([[True, False], [False, False]], False, smap.stable),
                                 failures=((float(smap.values[0]), float(smap.speeds[0]), "boom"),))
    df = pd.read_csv(failed.to_csv(tmp_path / "failed.csv"), dtype={"stable": "boolean", "error": str})
    assert df["stable"].isna().tolist() == [True, False, False, False] and df["error"].iloc[0] == "boom"
    assert np.isnan(df["spectral_radius"].iloc[0]) and df["ok"].tolist() == [False, True, True, True]


def test_the_branch_tables(tmp_path):
    """A branch's two tables (written from a branch made by hand: the format, not the continuation)."""
    def point(w, rho):
        return BranchPoint(w, (kf.LinkPeaks("rod", 1e-3 * w, 0.1, 1e6 * w, 0.2, 0.05),),
                           (LinkError("rod", 1e-5, 2e-5, 3e-5),), np.zeros(0, complex), rho, rho < 1.0)
    pts = tuple(point(w, rho) for w, rho in ((100.0, 0.5), (110.0, 0.9), (120.0, 1.2)))
    fold = Bifurcation("flip", 115.0, (110.0, 120.0), complex(-1.0, 0.0), True, False)
    branch = Branch("speed", "rad/s", pts, (fold,), 48, "radau3")
    files = kf.write_branch(branch, tmp_path)
    pts_csv = next(f for f in files if f.name == "branch.csv")
    df = check_table(pts_csv)
    assert df["speed_rad_s"].tolist() == [100.0, 110.0, 120.0]
    bif = check_table(tmp_path / "branch_bifurcations.csv")
    assert bif["bracket_lo_rad_s"].tolist() == [110.0] and bif["stable_after"].tolist() == [False]
    back = kf.read_branch(tmp_path)
    assert back.bifurcations[0].bracket == (110.0, 120.0)
    # a branch written before the convention (its brackets named bracket_lo / bracket_hi) reads too
    old = tmp_path / "branch_bifurcations.csv"
    old.write_text(old.read_text().replace("bracket_lo_rad_s", "bracket_lo").replace("bracket_hi_rad_s", "bracket_hi"))
    assert kf.read_branch(tmp_path).bifurcations[0].bracket == (110.0, 120.0)


def test_a_result_hands_itself_to_the_io_wing_at_call_time(folder, monkeypatch, tmp_path):
    """res.write and res.summary call the io wing's functions as they are when called (a patch of
    kedfem.io.report takes effect), though the analysis wing never imports it."""
    from kedfem.io import report
    res, _out = folder
    seen = []
    monkeypatch.setattr(report, "write_result", lambda r, out, **kw: seen.append((r, out, kw)) or "written")
    monkeypatch.setattr(report, "format_summary", lambda r, *a, **kw: "summary of " + r.scene.mech.name)
    assert res.write(tmp_path / "x", plots=False) == "written" and seen == [(res, tmp_path / "x", {"plots": False})]
    assert res.summary() == "summary of " + res.scene.mech.name
