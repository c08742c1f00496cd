"""Former home of one DDA judgement, now `kgm.judges.run` (docs/kgm/architecture.md): its names
stay importable from here for one release."""

from .judges.run import (DdaJudgement, RestCounter, RunPlan, block_displacements, block_speeds,  # noqa: F401
                         group_size, judge, run_params, sub_scene)
from .settings import DdaSettings  # noqa: F401
from .system import BlockSystem  # noqa: F401
