"""Cross-backend check: a run with Params(arch="gpu") gives the CPU answer.

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
    res = dd.simulate(scene, params=dd.Params(arch=arch, dt=0.01), duration=0.2, record_contacts=True)
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
