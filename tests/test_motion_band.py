"""The resolution floor sees the harmonics of a motion that whips through a near-toggle.

A crank-rocker 1e-5 m from its Grashof change point swings its follower through the near-toggle
in a small part of the cycle; its angular acceleration has harmonics to about 1300 per cycle. The
floor sampled the motion at 512 instants and saw 256 (its own limit); the levels it then allowed
(384/768/1536 at rtol 1e-3) all missed the whip, agreed, and printed 6.6e-4 for a follower peak
1.4e-2 off. The truth here is the closed-form position of the follower (two circles), not kedfem's
kinematics.
"""

import math

import numpy as np

import kedfem as kf
from kedfem.analysis import pipeline

A_, B_, C_, D_ = 0.1, 0.3, 0.1 + 1e-5, 0.3   # crank, coupler, follower, ground [m]
RPM = 100.0


def _near_change_point():
    m = kf.Mechanism("near change point")
    m.ground("O2", at=(0, 0))
    m.ground("O4", at=(D_, 0))
    m.joint("A", at=m.at_angle("O2", A_, math.radians(10.0)))
    m.joint("B", at=m.at_lengths(("A", B_), ("O4", C_), branch="open"))
    steel, sec = kf.Material(E=2.06e11, rho=7850.0), kf.Section.rectangle(0.02, 0.006)
    m.link("crank", "O2", "A", rigid=True, mass=0.2)
    m.link("coupler", "A", "B", material=steel, section=sec, elements=2)
    m.link("follower", "O4", "B", material=steel, section=sec, elements=2)
    m.drive("crank", speed=RPM * 2 * math.pi / 60)
    return m


def _closed_form_reach(level: float, samples: int = 1 << 15) -> int:
    """Highest harmonic of the follower's angular acceleration above ``level`` of its largest,
    from the follower angle of the two circles' intersection at ``samples`` crank angles."""
    th = math.radians(10.0) + np.arange(samples) * (2 * math.pi / samples)
    A = np.stack([A_ * np.cos(th), A_ * np.sin(th)], axis=1)
    d = np.array([D_, 0.0]) - A
    r = np.hypot(d[:, 0], d[:, 1])
    e = d / r[:, None]
    x = (B_ * B_ - C_ * C_ + r * r) / (2 * r)
    B = A + x[:, None] * e + np.sqrt(B_ * B_ - x * x)[:, None] * np.stack([-e[:, 1], e[:, 0]], axis=1)
    th4 = np.unwrap(np.arctan2(B[:, 1], B[:, 0] - D_))
    k = np.arange(samples // 2 + 1)
    alpha = np.abs(np.fft.rfft(th4 - th4.mean()))[1:] * k[1:] ** 2  # (k w)^2 |theta_k|, w = 1
    return int(np.flatnonzero(alpha > level * alpha.max()).max()) + 1


def test_the_floor_samples_a_near_toggle_whip_until_its_harmonics_end():
    sc = kf.Scene(_near_change_point(), rtol=1e-3)
    run = pipeline._Run(sc, None)
    level = 1e-3 * sc.rtol   # the level the resolution floor reads the motion at
    reach = run._motion_band(level=level) * sc.period   # harmonics per cycle
    truth = _closed_form_reach(level)
    assert truth > 1000   # the whip: far beyond the 256 harmonics 512 samples resolve
    assert 0.95 * truth <= reach <= 1.05 * truth, (reach, truth)
    # an ordinary four-bar keeps its first sampling (its harmonics end at 22 per cycle)
    import mechanisms
    plain = pipeline._Run(kf.Scene(mechanisms.build("four_bar"), rtol=1e-3), None)
    assert plain._motion_band(level=1e-6) * plain.scene.period < 64
    assert set(plain.__dict__["_band_cache"]) == {512}


def test_the_floor_does_not_read_round_off_as_harmonics():
    """At a tolerance far below round-off the level is held at MOTION_NOISE: an ordinary four-bar keeps
    its first sampling (at rtol 1e-13 the FFT's noise had read as harmonics to the sampling limit)."""
    import mechanisms
    run = pipeline._Run(kf.Scene(mechanisms.build("four_bar"), rtol=1e-3), None)
    reach = run._motion_band(level=1e-16) * run.scene.period
    assert reach < 128 and set(run.__dict__["_band_cache"]) == {512}

