"""Former home of the limit-equilibrium judges, now `kgm.judges` (docs/kgm/architecture.md):
its names stay importable from here for one release."""

from .faces import group_faces  # noqa: F401
from .judges.evaluation import Evaluation, Mode, critical_friction_of, governing, tie_key  # noqa: F401
from .judges.limits import F_MAX, F_MIN, PHI_MAX, POLE_SAMPLES, ROOT_K_TOL, SCAN_SAMPLES  # noqa: F401
from .judges.mechanisms import VELOCITY_TOL  # noqa: F401
from .judges.rigid import evaluate_rigid, rigid_modes  # noqa: F401
from .judges.sarma import evaluate_sarma, sarma_checks, sarma_modes  # noqa: F401
from .judges.toppling import toppling_check  # noqa: F401
from .kinds import ModeKind  # noqa: F401
from .system import BlockSystem  # noqa: F401
