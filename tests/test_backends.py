"""Cross-backend check: a run with Params(arch="gpu") gives the CPU answer (both on the Taichi
kernels, `Params.kernels="taichi"`: a small model would otherwise run in NumPy).

On a machine with CUDA this compares the GPU kernels with the CPU ones (the `gpu` marker: they
skip without an NVIDIA device, where "gpu" would only run the CPU kernels twice). Without a GPU,
"gpu" must fall back to the CPU cleanly (it must not probe OpenGL, which crashes headless
machines). Each runs in a fresh interpreter so the session's Taichi runtime stays on the CPU.
"""

import json
import os
import shutil
import subprocess
import sys

import pytest


def _nvidia_device() -> bool:
    """An NVIDIA driver is present (no Taichi start: that is what the tests do in a subprocess)."""
    return os.path.exists("/dev/nvidiactl") or shutil.which("nvidia-smi") is not None


needs_cuda = pytest.mark.skipif(
    not _nvidia_device(), reason="no NVIDIA device: the GPU kernels cannot be compared with the CPU's "
    "(test_gpu_falls_back_to_the_cpu checks the fallback)")

FALLBACK = """
import io, json, sys, contextlib
from ddatai import backend
err = io.StringIO()
with contextlib.redirect_stderr(err):
    arch = backend.ensure("gpu")
print(json.dumps({"arch": arch, "current": backend.current(), "again": backend.ensure("gpu")}))
"""


@pytest.mark.skipif(_nvidia_device(), reason="an NVIDIA device is present: the GPU tests run instead")
def test_gpu_falls_back_to_the_cpu():
    """Params(arch="gpu") on a machine without a GPU: Taichi starts on the CPU, without probing
    OpenGL (a segfault on headless machines), and asking again keeps it."""
    proc = subprocess.run([sys.executable, "-c", FALLBACK], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out == {"arch": "cpu", "current": "cpu", "again": "cpu"}
    assert "opengl" not in proc.stderr.lower()

CODE = """
import json, sys
sys.path.insert(0, "tests")
import ddatai as dd
from ddatai import backend
from cases import sliding_scene
out = {}
for arch in ("cpu", "gpu"):
    scene, block = sliding_scene(30.0, 20.0)
    res = dd.simulate(scene, params=dd.Params(arch=arch, dt=0.01, kernels="taichi"), duration=0.2,
                      record_contacts=True)
    out[arch] = {"arch": backend.current(), "xy": res.centroid[-1, block].tolist(),
                 "contacts": res.steps["contacts"].tolist(), "oc": res.steps["oc_iterations"].tolist()}
print(json.dumps(out))
"""


@pytest.mark.gpu
@needs_cuda
def test_gpu_arch_matches_cpu():
    proc = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    cpu, gpu = out["cpu"], out["gpu"]
    assert cpu["arch"] == "cpu"
    assert gpu["contacts"] == cpu["contacts"] and gpu["oc"] == cpu["oc"]
    for a, b in zip(gpu["xy"], cpu["xy"]):
        assert abs(a - b) < 1e-9


GRID = """
import json, sys
import numpy as np
sys.path.insert(0, "benchmarks")
import dataclasses
import ddatai as dd
from ddatai import backend
from scaling import grid_scene
out = {}
for arch in ("cpu", "gpu"):
    scene, params = grid_scene(144)
    params = dataclasses.replace(params, arch=arch, kernels="taichi", solver="scipy")
    res = dd.simulate(scene, params=params, steps=20, record_every=20)
    out[arch] = {"arch": backend.current(), "xy": res.vertices[-1].tolist(),
                 "contacts": res.steps["contacts"].tolist(), "oc": res.steps["oc_total"].tolist()}
print(json.dumps(out))
"""


@pytest.mark.gpu
@needs_cuda
def test_gpu_grid_matches_cpu():
    """A 12 × 12 grid settling from rest (~600 contacts, parallel detection and assembly with
    atomic adds on a GPU): the same contacts and solves, positions within 1e-9 m."""
    import numpy as np

    proc = subprocess.run([sys.executable, "-c", GRID], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    cpu, gpu = out["cpu"], out["gpu"]
    assert gpu["contacts"] == cpu["contacts"] and gpu["oc"] == cpu["oc"]
    assert np.abs(np.array(gpu["xy"]) - np.array(cpu["xy"])).max() < 1e-9
