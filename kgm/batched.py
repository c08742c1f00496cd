"""Former home of many DDA judgements in one run, now `kgm.judges.batch`
(docs/kgm/architecture.md): its names stay importable from here for one release."""

from .judges.batch import Member, judge_many, judge_members  # noqa: F401
from .judges.run import (RestCounter, block_displacements, block_speeds, group_size, judge, run_params,  # noqa: F401
                         sub_scene)
from .settings import DdaSettings  # noqa: F401
from .system import BlockSystem  # noqa: F401
