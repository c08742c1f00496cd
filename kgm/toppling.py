"""Former home of the toppling rows and their judge, now `kgm.candidates` (the row geometry)
and `kgm.judges.toppling` (the Goodman–Bray recursion; docs/kgm/architecture.md): their names
stay importable from here for one release."""

from .candidates import (BASE_MIN_COS, INTERFACE_MIN_COS, ROW_BASE_ANGLE, ROW_PIVOT_TOL, RowBlock,  # noqa: F401
                         TopplingRow, row_geometry, toppling_row, upslope_neighbours)
from .judges.limits import BISECTION_STEPS, F_MAX, F_MIN, PHI_MAX  # noqa: F401
from .judges.toppling import (BlockStep, recursion, row_critical_friction, row_factor_of_safety,  # noqa: F401
                              toe_force, toppling_check, toppling_mode, with_toppling)
from .faces import group_faces  # noqa: F401
from .judges.evaluation import Mode  # noqa: F401
from .kinds import BlockState, ModeKind  # noqa: F401
from .system import BARTON_ITERATIONS, BARTON_TOL, BlockSystem  # noqa: F401
