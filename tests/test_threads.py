"""Tests of kedfem.solvers.threads (the BLAS thread policy) and periodic.solve's signature."""

from __future__ import annotations

import inspect
import sys

import pytest

from kedfem.solvers import periodic, threads


def _blas_threads():
    """Thread counts of the loaded BLAS libraries."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    return [d["num_threads"] for d in threadpoolctl.threadpool_info() if d["user_api"] == "blas"]


def test_one_blas_thread_limits_and_restores():
    before = _blas_threads()
    if not before:
        pytest.skip("no BLAS library loaded")
    with threads.one_blas_thread():
        assert set(_blas_threads()) == {1}
    assert _blas_threads() == before


def test_blas_threads_nest_and_restore_on_exception():
    before = _blas_threads()
    if not before:
        pytest.skip("no BLAS library loaded")
    with pytest.raises(RuntimeError):
        with threads.blas_threads(2):
            with threads.one_blas_thread():
                assert set(_blas_threads()) == {1}
            assert max(_blas_threads()) <= 2
            raise RuntimeError
    assert _blas_threads() == before


def test_without_threadpoolctl_the_contexts_do_nothing(monkeypatch):
    monkeypatch.setattr(threads, "_CONTROLLER", None)
    monkeypatch.setitem(sys.modules, "threadpoolctl", None)  # import fails
    with threads.one_blas_thread():
        pass
    assert threads._CONTROLLER is False
    with threads.blas_threads(3):
        pass


def test_periodic_solve_has_an_explicit_signature():
    params = inspect.signature(periodic.solve).parameters
    kinds = {p.kind for p in params.values()}
    assert inspect.Parameter.VAR_POSITIONAL not in kinds
    assert inspect.Parameter.VAR_KEYWORD not in kinds
    assert list(params)[:6] == ["M", "C", "K", "Q", "period", "hold"]
    assert {"n", "delta", "method", "approximant", "memory_budget", "max_condition", "workers",
            "Kz", "Qz", "Cz"} <= set(params)
    assert "Parameters" in periodic.solve.__doc__ and "one_blas_thread" in periodic.solve.__doc__
