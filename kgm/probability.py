"""Former home of the probabilistic key group analysis, now `kgm.studies`
(docs/kgm/architecture.md): its names stay importable from here for one release."""

from .kinds import METHOD_NAMES as METHODS  # noqa: F401
from .kinds import SAMPLINGS  # noqa: F401
from .studies.probabilistic import probabilistic  # noqa: F401
from .studies.sampling import read_variables, sample_seeds, sample_variables, variables_from_mapping  # noqa: F401
from .studies.study import HEADER_MARK, SampleRow, Study, read_study, write_frequency_png  # noqa: F401
