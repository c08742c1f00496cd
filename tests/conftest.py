"""Shared test set-up: Taichi on the CPU backend, double precision (via ddatai.backend)."""

import pytest


@pytest.fixture(scope="session", autouse=True)
def _taichi_cpu():
    # Only tests that run kernels need Taichi, but starting it once per session keeps the
    # per-test cost low; ddatai.backend is the one place that calls ti.init.
    from ddatai import backend

    backend.ensure("cpu")
    yield
