"""Former home of the DDA judge, now `kgm.judges.dda` (the factor of safety and critical friction
on DDA verdicts) and `kgm.judges.run` (one judgement; docs/kgm/architecture.md): their names
stay importable from here for one release."""

from .judges.dda import DdaEvaluation, DdaTiming, evaluate_dda, time_sub_and_whole  # noqa: F401
from .judges.batch import judge_many  # noqa: F401
from .judges.run import DdaJudgement, group_size, judge, run_params, sub_scene  # noqa: F401
from .settings import DdaSettings  # noqa: F401
from .system import BlockSystem  # noqa: F401
