"""The start record of the scaling benchmark's jointed slope (`scaling_scenes.slope_scene(n)`):
held, released, in doubt, solves, and the CPU time of the build, the stage and one step.

    PYTHONPATH=$PWD python benchmarks/slope_stage.py 400     # 391 free blocks (1600: 1,537)
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
from scaling_scenes import slope_scene  # noqa: E402

n = int(sys.argv[1])
scene, params = slope_scene(n)
t = time.process_time()
r = dd.simulate(scene, params, steps=1)
print(n, dict(zip(r.start.dtype.names, r.start[0].tolist())), "CPU incl. build+1 step",
      round(time.process_time() - t, 2))
