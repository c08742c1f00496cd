"""Cross-backend check: a run with Params(arch="gpu") gives the CPU answer (both on the Taichi
kernels, `Params.kernels="taichi"`: a small model would otherwise run in NumPy).

On a machine with CUDA (or Vulkan) this compares the GPU kernels with the CPU ones; without a
GPU, "gpu" must fall back to the CPU cleanly (it must not probe OpenGL, which crashes headless
machines). Runs in a fresh interpreter so the session's Taichi runtime stays on the CPU.
"""

import json
import subprocess
import sys

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
