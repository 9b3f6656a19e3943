"""Natural frequencies against the reference data of docs/references.md (sections 1-3)."""

import math

import numpy as np
import pytest

import kedfem as kf

E, RHO, L = 2.0e11, 7800.0, 2.0
SEC = kf.Section.circle(0.01)
BETA_L = {
    "clamped-free": [1.875104, 4.694091, 7.854757],
    "clamped-clamped": [4.730041, 7.853205, 10.995608],
    "clamped-pinned": [3.926602, 7.068583, 10.210176],
    "pinned-pinned": [math.pi, 2 * math.pi, 3 * math.pi],
}


def beam(bc, n):
    m = kf.Mechanism(bc)
    left, right = bc.split("-")
    m.ground("A", at=(0, 0), clamped=(left == "clamped"))
    if right == "free":
        m.joint("B", at=(L, 0))
    elif right == "clamped":
        m.ground("B", at=(L, 0), clamped=True)
    else:  # pinned: transverse support, free to slide axially
        m.slider("B", at=(L, 0), axis=(1, 0))
    m.link("beam", "A", "B", material=kf.Material(E, RHO), section=SEC, elements=n)
    return m


def bending_frequencies(m, count):
    """Lowest ``count`` transverse frequencies (axial modes lie far above here)."""
    f = np.asarray(kf.natural_frequencies(m, n_modes=count + 2).frequencies)
    return f[:count]


@pytest.mark.parametrize("bc", list(BETA_L))
def test_beam_frequencies_20_elements(bc):
    w0 = math.sqrt(E * SEC.I / (RHO * SEC.A * L**4))
    exact = np.array(BETA_L[bc]) ** 2 * w0 / (2 * math.pi)
    f = bending_frequencies(beam(bc, 20), 3)
    assert np.max(np.abs(f / exact - 1)) < 1e-4


def test_frequency_error_falls_as_h4():
    """Hermite cubic, consistent mass: eigenvalue error O(h^4) (Strang & Fix)."""
    w0 = math.sqrt(E * SEC.I / (RHO * SEC.A * L**4))
    exact = np.array(BETA_L["clamped-free"][:2]) ** 2 * w0 / (2 * math.pi)
    ns = np.array([4, 8, 16])
    err = np.array([np.abs(bending_frequencies(beam("clamped-free", n), 2) / exact - 1) for n in ns])
    for mode in range(2):
        slope = np.polyfit(np.log(1.0 / ns), np.log(err[:, mode]), 1)[0]
        assert 3.6 < slope < 4.4, (mode, slope, err[:, mode])


@pytest.mark.parametrize("P,ref", [
    (0.0, [4.9713, 19.8851, 44.7415, 79.5404, 124.2818]),
    (10.0, [5.0728, 19.9874, 44.8439, 79.6429, 124.3844]),
    (100.0, [5.9090, 20.8860, 45.7561, 80.5599, 125.3037]),
    (1000.0, [11.2577, 28.3462, 54.0370, 89.2134, 134.1511]),
])
def test_axially_loaded_pinned_beam(P, ref):
    """Section 2: tension P from a load at the sliding support, through the kinetostatics."""
    m = beam("pinned-pinned", 20)
    m.load("tension", "B", force=(P, 0.0))
    f = np.asarray(kf.natural_frequencies(m, n_modes=5, effects=("axial_stiffening", "loads")).frequencies)
    np.testing.assert_allclose(f, ref, rtol=1e-3)


def test_compression_lowers_and_buckling_load():
    m = beam("pinned-pinned", 20)
    pcr = math.pi**2 * E * SEC.I / L**2
    assert pcr == pytest.approx(242.24, rel=1e-4)
    m.load("push", "B", force=(-0.5 * pcr, 0.0))
    f = np.asarray(kf.natural_frequencies(m, n_modes=1, effects=("axial_stiffening", "loads")).frequencies)
    assert f[0] == pytest.approx(4.9713 * math.sqrt(0.5), rel=1e-3)


GAMMA_REF = {1: 3.5432, 2: 3.6218, 3: 3.7435, 4: 3.8977, 5: 4.0739, 6: 4.2632, 8: 4.6571, 10: 5.0490}


@pytest.mark.parametrize("gamma", list(GAMMA_REF))
def test_rotating_cantilever_in_plane(gamma):
    """Section 3: a cantilever link driven about its clamped ground joint."""
    sec = kf.Section.rectangle(0.01, 0.01)
    Lb = 1.0
    c = Lb**2 * math.sqrt(RHO * sec.A / (E * sec.I))
    m = kf.Mechanism("rotor")
    m.ground("O", at=(0, 0), clamped=True)
    m.joint("T", at=(Lb, 0))
    m.link("blade", "O", "T", material=kf.Material(E, RHO), section=sec, elements=12)
    m.drive("blade", speed=gamma / c)
    f = kf.natural_frequencies(m, n_modes=2, effects=("coupling", "axial_stiffening"))
    lam = f.frequencies[0] * 2 * math.pi * c
    assert lam == pytest.approx(GAMMA_REF[gamma], rel=0.01)
    # each effect alone moves the frequency the expected way
    if gamma < 3.5:
        soft = kf.natural_frequencies(m, n_modes=1, effects=("coupling",))
    else:  # centripetal softening alone makes the blade unstable: reported negative, with a warning
        with pytest.warns(RuntimeWarning, match="negative"):
            soft = kf.natural_frequencies(m, n_modes=1, effects=("coupling",))
    soft = soft.frequencies[0] * 2 * math.pi * c
    stiff = kf.natural_frequencies(m, n_modes=1, effects=("axial_stiffening",)).frequencies[0] * 2 * math.pi * c
    assert soft < 3.5160 < stiff
    assert np.sign(soft) * soft**2 == pytest.approx(3.5160**2 - gamma**2, rel=2e-3, abs=2e-3)


def test_frequencies_over_cycle_and_modes():
    import mechanisms
    m = mechanisms.build("slider_crank")
    r = kf.natural_frequencies(m, n_modes=3, steps=12, effects=("coupling", "axial_stiffening"))
    assert r.frequencies.shape == (12, 3)
    assert np.all(np.diff(r.frequencies, axis=1) > 0)
    r1 = kf.natural_frequencies(m, n_modes=2, modes=True)
    phi = r1.shapes
    M = kf.global_matrices(m).M.toarray()
    np.testing.assert_allclose(phi.T @ M @ phi, np.eye(2), atol=1e-10)
    # rod's first pinned-pinned bending frequency (references section 5): 203.2 Hz
    assert r1.frequencies[0] == pytest.approx(203.2, rel=2e-3)


def test_geometric_nonlinearity_refused():
    with pytest.raises(kf.InputError, match="geometric_nonlinearity"):
        kf.natural_frequencies(beam("clamped-free", 2), effects=("geometric_nonlinearity",))
    with pytest.raises(kf.InputError, match="known effects"):
        kf.natural_frequencies(beam("clamped-free", 2), effects=("magic",))
