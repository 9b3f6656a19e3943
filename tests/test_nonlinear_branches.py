"""Non-linear responses of the four-bar preset (issue 24): Newton converges quadratically on a
branch; pushed from 100 to 600 rpm, every kf.solve ends in a converged response with a verdict
from its own orbit, or in a named NonlinearSolveError, never in the numbers of a diverged iterate."""

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import kedfem as kf
from kedfem.catalogue import info

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from linkages import strip_crank_rocker  # noqa: E402  (a new user's linkage, not in the catalogue)

RPM = 2 * math.pi / 60


def scene(rpm, **kw):
    return info("four_bar").scene({}, speed=rpm * RPM, **kw)


def test_newton_converges_quadratically_from_a_neighbour(monkeypatch):
    from kedfem.analysis import problem
    monkeypatch.setattr(problem, "CHORD_CHANGE", 0.0)  # full Newton steps only: the tangent's own rate
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = kf.solve(scene(300, steps=48, estimate=False))
        res = kf.solve(scene(303, steps=48, estimate=False, eps=1e-9), start=base)
    h = np.array(res.history)
    assert res.converged and len(h) <= 8, h
    # the last two corrections: each below a constant times the square of the one before (down to
    # round-off, ~1e-11): the quadratic rate of Newton's method with the consistent tangent
    assert h[-2] <= 50.0 * h[-3] ** 2 and h[-1] <= 50.0 * h[-2] ** 2 + 1e-10, h


def test_a_speed_sweep_ends_in_answers_or_named_failures():
    seen = []
    for rpm in (100, 300, 450, 600):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                res = kf.solve(scene(rpm, steps=24, estimate=False))
            except kf.NonlinearSolveError as e:
                assert f"{rpm:g} rpm" in str(e) and "Next:" in str(e)
                seen.append("failure")
                continue
        assert res.converged and res.stability.verdict in ("stable", "unstable", "marginal")
        assert res.stable == (res.stability.verdict == "stable")
        for p in res.peaks():  # an answer: finite and not the runaway of a diverged iterate
            assert np.isfinite([p.deflection, p.stress]).all() and p.deflection < 0.05
        seen.append(res.stability.verdict)
    assert seen[:2] == ["stable", "stable"], seen


def test_a_fixed_point_iteration_that_fails_is_a_named_error():
    """The paper's iteration, asked explicitly and limited to 3 solves at 350 rpm: no result."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(kf.NonlinearSolveError, match="did not converge within max_iter = 3") as e:
            kf.solve(scene(350, steps=24, nonlinear_method="fixed-point", max_iter=3))
    assert "nonlinear_method='newton'" in str(e.value)


def test_the_command_line_exits_non_zero_and_writes_no_peaks(tmp_path):
    """The same failure from `kedfem run`: a one-line named error, exit status non-zero, and no
    output folder with peaks in it."""
    import subprocess
    import sys
    (tmp_path / "s.toml").write_text('mechanism = "four_bar"\nspeed_rpm = 350\nsteps = 24\n'
                                     '[solver]\nnonlinear_method = "fixed-point"\nmax_iter = 3\n')
    r = subprocess.run([sys.executable, "-m", "kedfem.cli", "run", "s.toml", "--out", "out"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode != 0
    assert "no periodic response found at 350 rpm" in r.stderr and "Traceback" not in r.stderr
    assert not list(tmp_path.rglob("peaks.csv"))


def test_newton_stops_on_the_rate_of_a_coarser_level(monkeypatch):
    """A finer level's Newton stops on a change whose successor the coarser level's rate predicts
    below eps / 10, one solve early, and the response it returns is that close to the solution
    (full Newton steps: a chord step's solution is not stopped on a prediction)."""
    from kedfem.analysis import problem
    from kedfem.analysis.pipeline import _Run
    monkeypatch.setattr(problem, "CHORD_CHANGE", 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = _Run(scene(200))
        ti, coarse = run.problem(48)
        c = coarse.solve(None, eps=1e-4, max_iter=30)
        assert c.converged and c.rate is not None and c.predicted is None
        ti, fine = run.problem(96)
        x0 = c.discrete.at(ti)
        quick = fine.solve(x0, eps=1e-4, max_iter=30, rate=c.rate)
        plain = fine.solve(x0, eps=1e-4, max_iter=30)
        ref = fine.solve(x0, eps=1e-9, max_iter=30)
    assert quick.converged and plain.converged and ref.converged
    # without a rate only a change below eps stops it; with one, a solve earlier
    assert quick.predicted is not None and plain.predicted is None and plain.history[-1] <= 1e-4
    assert quick.iterations == plain.iterations - 1 and quick.history == plain.history[:-1]
    assert quick.history[-1] > 1e-4 and quick.predicted <= 1e-5
    U, Uref = (s.discrete.at(ti)[0] for s in (quick, ref))
    err = float(np.linalg.norm(U - Uref) / np.linalg.norm(Uref))
    # the distance from the solution: below eps, and below the prediction (an upper estimate)
    assert err <= 1e-4 and err <= quick.predicted, (err, quick.predicted)


def test_a_continuation_starts_from_the_given_start():
    """Pushed past where Newton converges from the linear response, a solve given the result at a
    lower speed continues from that speed (fewer steps), to the same response as on its own."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = kf.solve(scene(340, steps=24, estimate=False))
        given = kf.solve(scene(400, steps=24, estimate=False), start=base)
        alone = kf.solve(scene(400, steps=24, estimate=False))
    assert "from 340 rpm" in given.path and "the given start" in given.path, given.path
    assert "from 340 rpm" not in alone.path and "the linear response" in alone.path, alone.path
    assert given.iterations < alone.iterations  # measured 175 and 218 linear solves (372 before the
    # first correction decided the continuation's steps)
    a = np.array([[p.deflection, p.stress] for p in given.peaks()])
    b = np.array([[p.deflection, p.stress] for p in alone.peaks()])
    assert np.max(np.abs(a / b - 1)) < 1e-6


def test_chord_steps_reach_newtons_solution_with_fewer_factorisations(monkeypatch):
    """Once a full Newton solve changes the response by at most CHORD_CHANGE, the steps after it
    are chord steps on its kept factorisations: the same solution to the tolerance, fewer
    factorisations. With CHORD_RHO below the orbit's spectral radius every step is full."""
    from kedfem.analysis import problem
    from kedfem.analysis.pipeline import _Run
    from kedfem.solvers import collocation
    factorised = []
    real = collocation.solve
    monkeypatch.setattr(collocation, "solve",
                        lambda *a, **k: factorised.append(1) or real(*a, **k))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = _Run(scene(200))
        ti, coarse = run.problem(48)
        x0 = coarse.solve(None, eps=1e-4, max_iter=30).discrete.at(run.problem(96)[0])
        out = {}
        for label, change, rho in (("chord", problem.CHORD_CHANGE, problem.CHORD_RHO),
                                   ("full", 0.0, problem.CHORD_RHO), ("near limit", problem.CHORD_CHANGE, 0.0)):
            monkeypatch.setattr(problem, "CHORD_CHANGE", change)
            monkeypatch.setattr(problem, "CHORD_RHO", rho)
            ti, fine = run.problem(96)
            factorised.clear()
            s = fine.solve(x0, eps=1e-10, max_iter=30)
            out[label] = (s, len(factorised), fine.chord_steps)
    (chord, n_chord, steps), (full, n_full, none), (near, n_near, none2) = out.values()
    assert chord.converged and full.converged and near.converged
    assert steps >= 1 and none == 0 and none2 == 0
    assert n_chord < n_full and n_near == n_full, (n_chord, n_full, n_near)
    U, Uf = chord.discrete.at(ti)[0], full.discrete.at(ti)[0]
    assert np.linalg.norm(U - Uf) <= 1e-8 * np.linalg.norm(Uf)


def test_chord_steps_keep_the_solve_and_its_stability_error(monkeypatch):
    """kf.solve with chord steps against full Newton steps: the same peaks to the iteration's
    tolerance, and the spectral radius of the frozen tangents within the printed error (the
    lag of a level's tangent shrinks with the change between levels, as its error does)."""
    from kedfem.analysis import problem
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chord = kf.solve(scene(250))
        monkeypatch.setattr(problem, "CHORD_CHANGE", 0.0)
        full = kf.solve(scene(250))
    assert chord.converged and full.converged and chord.elements == full.elements
    for a, b in zip(chord.peaks(), full.peaks()):
        assert abs(a.stress - b.stress) <= 1e-5 * b.stress and abs(a.deflection - b.deflection) <= 1e-5 * b.deflection
    st, sf = chord.stability, full.stability
    assert st.verdict == sf.verdict == "stable"
    assert abs(st.spectral_radius - sf.spectral_radius) <= st.error, (st, sf)


def test_a_chord_step_is_taken_only_inside_an_iteration_and_near_its_frozen_tangent():
    """Inside an iteration (solve, polish) the step after a full solve is a chord step near that
    solve's iterate, and a full solve from an iterate far from it (an iteration started again
    elsewhere, as Anderson's after a failed fixed-point iteration). Called directly (the
    continuation's bordered corrector differentiates G in speed) every step is Newton's."""
    from kedfem.analysis.pipeline import _Run
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = _Run(scene(200))
        ti, coarse = run.problem(48)
        x0 = coarse.solve(None, eps=1e-4, max_iter=30).discrete.at(run.problem(96)[0])
        ti, fine = run.problem(96)
        with fine._chords(fresh=True):
            _d, U1, V1 = fine.step(*x0)          # full: changes the interpolated start by ~1e-2
            assert fine._chord is not None and fine.chord_steps == 0
            fine.step(U1, V1)                    # near it: a chord step
            assert fine.chord_steps == 1
            d, _U, _V = fine.step(np.zeros_like(U1), np.zeros_like(V1))  # far from it: full
            assert fine.chord_steps == 1 and not d.chord
            _d, U1, V1 = fine.step(*x0)
            assert fine._chord is not None
        d, _U, _V = fine.step(U1, V1)            # outside: Newton's full step
        assert fine.chord_steps == 1 and not d.chord


def test_a_relaxed_iteration_from_an_interpolated_start_takes_no_chord_step(monkeypatch):
    """A review's case: the relaxation from a coarser level's interpolated start keeps half the
    start's kinematic defect per step, which a chord correction (free of one) never removes;
    with chord steps it stopped 3.4e-3 from the solution at eps 1e-4. A chord step is taken only
    from states whose kinematic rows hold (collocation.kinematic_defect), so it ends where the
    full steps end."""
    from kedfem.analysis.pipeline import _Run
    from kedfem.solvers import collocation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = _Run(scene(200))
        ti, coarse = run.problem(24)
        c = coarse.solve(None, eps=1e-8, max_iter=40)
        ti, fine = run.problem(96)
        x0 = c.discrete.at(ti)
        assert collocation.kinematic_defect(*x0, fine.period) > 1e-4
        ref = fine.solve(x0, eps=1e-11, max_iter=80, method="relaxation")
        ti, fine = run.problem(96)
        s = fine.solve(x0, eps=1e-4, max_iter=80, method="relaxation")
    U, Uref = s.discrete.instant_states()[0], ref.discrete.instant_states()[0]
    assert s.converged and np.linalg.norm(U - Uref) <= 1e-6 * np.linalg.norm(Uref)
    assert collocation.kinematic_defect(*ref.discrete.instant_states(), fine.period) < 1e-12


def test_a_level_reached_by_continuation_keeps_its_elements_snapped_to_the_kinks(monkeypatch):
    """A level whose Newton fails is reached by continuation in speed, whose problems at the other
    speeds are on uniform elements; the target's own problem (elements ending where the block
    crosses the rocker's nodes) is pinned, so a continuation of more speeds than the family keeps
    does not end on uniform elements (a review found it did, with two problems kept: the level's
    result then compared with levels on snapped elements)."""
    from kedfem.analysis import branch, pipeline
    from kedfem.catalogue import build
    monkeypatch.setattr(branch.Family, "KEEP", 2)
    seen = []
    orig = pipeline._Run.homotopy

    def homotopy(self, prob, failed, eps, origin="the linear response"):
        out = orig(self, prob, failed, eps, origin)
        seen.append((prob.edges, out.discrete.raw.edges, out.converged))
        return out

    monkeypatch.setattr(pipeline._Run, "homotopy", homotopy)
    sc = kf.Scene(build("inverted_slider_crank"), effects=("inertia", "coupling", "axial_stiffening",
                                                           "geometric_nonlinearity"),
                  damping=kf.ModalDamping(0.02), max_iter=1, rtol=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(sc)
    assert seen and res.error.met
    for want, got, converged in seen:
        assert converged and want is not None and got is not None and np.array_equal(want, got)


def test_a_continuation_step_too_long_is_shortened_before_its_newton_iteration(monkeypatch):
    """Newton's first correction from the predictor is the predictor's error: a step whose first
    correction exceeds PREDICTOR_REJECT times the aim is shortened without its Newton iteration
    (which failed after 12-16 solves at 0.12 and more), so the continuation to 350 rpm costs
    fewer linear solves (173 with the iteration-count step control) and gives the same response
    as Newton from a nearby given start."""
    from kedfem.analysis import branch
    firsts, solved = [], []
    orig_first, orig_solve = branch._first_correction, branch.Family.solve

    def first(family, xp, lam):
        g, c0 = orig_first(family, xp, lam)
        firsts.append((lam, c0))
        return g, c0

    def solve(self, lam, x0, eps, max_iter=30):
        solved.append(lam)
        return orig_solve(self, lam, x0, eps, max_iter)

    monkeypatch.setattr(branch, "_first_correction", first)
    monkeypatch.setattr(branch.Family, "solve", solve)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(scene(350, steps=24, estimate=False))
    assert "continuation in speed" in res.path, res.path
    limit = branch.PREDICTOR_REJECT * branch.PREDICTOR_CHANGE
    rejected = [lam for lam, c0 in firsts if c0 > limit]
    assert rejected and not set(rejected) & set(solved), (rejected, firsts)
    assert res.iterations <= 140, res.iterations  # measured 127
    monkeypatch.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        near = kf.solve(scene(345, steps=24, estimate=False), start=res)
        again = kf.solve(scene(350, steps=24, estimate=False), start=near)
    a = np.array([[p.deflection, p.stress] for p in res.peaks()])
    b = np.array([[p.deflection, p.stress] for p in again.peaks()])
    assert np.max(np.abs(a / b - 1)) < 1e-5


def test_a_continuation_in_speed_reports_its_progress_and_the_time_left(monkeypatch):
    """The continuation a solve falls back on reports each speed it reaches (to the solve's progress
    bar, with the seconds left at its pace so far), from its start up to the target."""
    from kedfem.analysis import homotopy
    calls = []
    orig = homotopy.ContinuationProgress.__call__

    def record(self, lam, start, steps):
        orig(self, lam, start, steps)
        calls.append((abs(lam), abs(start), steps, self.left, self.target))

    monkeypatch.setattr(homotopy.ContinuationProgress, "__call__", record)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(scene(350, steps=24, estimate=False))
    assert "continuation in speed" in res.path, res.path
    assert len(calls) >= 3
    lams = [c[0] for c in calls]
    assert calls[0][0] == calls[0][1] and calls[0][2] == 0  # the start first
    assert all(b >= a for a, b in zip(lams, lams[1:]))  # (no fold on this branch)
    assert math.isclose(lams[-1], 350 * RPM, rel_tol=1e-12) and calls[-1][4] == lams[-1]
    assert all(c[3] is not None and c[3] >= 0 for c in calls[1:])


def test_the_continuation_forecast_is_the_pace_so_far_times_the_speed_left(monkeypatch):
    """``ContinuationProgress``: seconds left = seconds since the start was found x speed still to
    cover / speed covered; shown on the bar; logged once, at the third step, when long."""
    from kedfem.analysis import homotopy
    clock = iter([100.0, 104.0, 108.0, 112.0])
    monkeypatch.setattr(homotopy.time, "perf_counter", lambda: next(clock))

    class Bar:
        text = ""

        def set_postfix_str(self, s, refresh=True):
            self.text = s

    bar = Bar()
    p = homotopy.ContinuationProgress("m", 100.0, 48, bar)
    p(20.0, 20.0, 0)
    assert p.left is None and "48 time elements" in bar.text
    p(22.0, 20.0, 1)  # 2 rad/s in 4 s: 78 rad/s left take 156 s
    assert math.isclose(p.left, 156.0) and bar.text.endswith("about 156 s left, 1 step")
    p(30.0, 20.0, 2)  # 10 rad/s in 8 s: 70 left, 56 s
    assert math.isclose(p.left, 56.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import logging
        records = []
        handler = logging.Handler()
        handler.emit = records.append
        logging.getLogger("kedfem.analysis.pipeline").addHandler(handler)
        try:
            p(40.0, 20.0, 4)  # 20 in 12 s: 60 left, 36 s (> LONG_CONTINUATION): said once (the third
            # step failed and was shortened: the fourth is the first call past the third)
        finally:
            logging.getLogger("kedfem.analysis.pipeline").removeHandler(handler)
    assert math.isclose(p.left, 36.0)
    assert len(records) == 1 and "about 36 s more" in records[0].getMessage()
    # not before a tenth of the way: the first steps are short while the step control settles
    clock = iter([0.0, 5.0, 40.0])
    monkeypatch.setattr(homotopy.time, "perf_counter", lambda: next(clock))
    q = homotopy.ContinuationProgress("m", 100.0, 48, None)
    logging.getLogger("kedfem.analysis.pipeline").addHandler(handler)
    try:
        q(20.0, 20.0, 0)
        q(22.0, 20.0, 3)  # 2.5 % of the way: 155 s forecast, not said
        n_early = len(records)
        q(40.0, 20.0, 5)  # 25 %: 120 s, said
    finally:
        logging.getLogger("kedfem.analysis.pipeline").removeHandler(handler)
    assert n_early == 1 and len(records) == 2 and "about 120 s more" in records[1].getMessage()
    # said again when the forecast has doubled (the pace slows toward a resonance: said once, as
    # it crossed the threshold, it read "about 10 s more" where 60 s followed), at most 3 times
    clock = iter([0.0, 1.0, 2.7, 8.0, 20.0, 45.0, 200.0])
    monkeypatch.setattr(homotopy.time, "perf_counter", lambda: next(clock))
    r = homotopy.ContinuationProgress("m", 100.0, 48, None)
    logging.getLogger("kedfem.analysis.pipeline").addHandler(handler)
    try:
        r(20.0, 20.0, 0)
        for lam, steps in ((40.0, 3), (42.0, 4), (44.0, 5), (46.0, 6), (48.0, 7), (50.0, 8)):
            r(lam, 20.0, steps)
    finally:
        logging.getLogger("kedfem.analysis.pipeline").removeHandler(handler)
    said = [m.getMessage() for m in records[2:]]
    # forecasts 3.0, 7.1, 18.7 (said), 41.5 (said: > 2 x 18.7), 83.6 (said: > 2 x 41.5), 333 (not: 3 said)
    assert len(said) == 3 and [s_.split("about ")[1].split(" s")[0] for s_ in said] == ["19", "42", "84"], said


def _strip_crank_rocker(rpm):
    """A new user's crank-rocker (``benchmarks/linkages.py``), 3 mm strip coupler, with the
    geometric non-linearity on 48 time elements."""
    return kf.Scene(strip_crank_rocker(rpm, coupler_h=0.003), effects=("inertia", "coupling", "geometric_nonlinearity"),
                    damping=kf.ModalDamping(0.02), steps=48, estimate=False)


def test_the_mesh_check_of_a_non_linear_result_starts_from_it(monkeypatch):
    """The mesh check's comparison solve (half the elements per link) of a result reached by
    continuation in speed starts from the result on the nodes both meshes share: no continuation of
    its own (a new user's took longer than the solve and logged a second fallback warning), and the
    same comparison peaks as the comparison model's solve from the linear response, which there
    falls back on the continuation too. (Closer to its limit, at 350 rpm, Newton from the
    four-bar preset's result on two elements per link does not converge either, and the check
    falls back on the continuation as the solve did.)"""
    from kedfem.analysis import mesh_check, pipeline
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(_strip_crank_rocker(2250))
        assert "continuation in speed" in res.path
        calls = []
        orig = pipeline._Run.homotopy

        def homotopy(self, *a, **k):
            calls.append(self.scene.mech.name)
            return orig(self, *a, **k)

        monkeypatch.setattr(pipeline._Run, "homotopy", homotopy)
        est = kf.mesh_error(res)
        assert not calls
        coarse = mesh_check.comparison_mesh(res.scene.mechanism)
        import dataclasses
        cold = kf.solve(dataclasses.replace(res.scene, mechanism=coarse))
        assert calls  # from the linear response the comparison model needs the continuation
    fine = {p.link: p for p in res.peaks()}
    for p in cold.peaks():
        e = est.link(p.link)
        lk = res.scene.mechanism.links[p.link]
        div = 1.0 - (lk.elements / coarse.links[p.link].elements) ** e.rate
        want = abs(fine[p.link].deflection - p.deflection) / fine[p.link].deflection / abs(div)
        assert math.isclose(e.deflection, want, rel_tol=1e-3, abs_tol=1e-9), (p.link, e.deflection, want)


def test_a_response_reached_by_a_run_up_carries_its_own_orbits_multipliers():
    """The run-up's last Newton may end on a chord step, whose Floquet multipliers are those of a
    tangent frozen at another iterate (a new user's Watt six-bar by a resonance read a spectral
    radius of 0.6845 where its response's own is 0.6787; here 0.242025 against 0.242138). The
    result's multipliers are those a Newton solve started from it finds, to round-off."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(scene(350, steps=48, estimate=False))
        again = kf.solve(scene(350, steps=48, estimate=False), start=res)
    assert "continuation in speed" in res.path and "continuation" not in again.path
    rho, rho_again = res.stability.spectral_radius, again.stability.spectral_radius
    assert abs(rho / rho_again - 1) < 1e-6, (rho, rho_again)
    assert all(abs(p.deflection / q.deflection - 1) < 1e-8 for p, q in zip(res.peaks(), again.peaks()))
