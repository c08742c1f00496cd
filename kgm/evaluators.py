"""Former home of the limit-equilibrium judges, now `kgm.judges` (docs/kgm/architecture.md):
its names stay importable from here for one release."""

from .judges.evaluation import Evaluation, critical_friction_of, governing, tie_key  # noqa: F401
from .judges.limits import F_MAX, F_MIN, PHI_MAX, POLE_SAMPLES, ROOT_K_TOL, SCAN_SAMPLES  # noqa: F401
from .judges.mechanisms import VELOCITY_TOL  # noqa: F401
from .judges.rigid import evaluate_rigid  # noqa: F401
from .judges.sarma import evaluate_sarma, sarma_checks, sarma_modes  # noqa: F401
