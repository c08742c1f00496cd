"""Former home of the block system, its faces and the rigid judge, now `kgm.system`,
`kgm.build`, `kgm.faces` and `kgm.judges.rigid` (docs/kgm/architecture.md): their names stay
importable from here for one release."""

from .build import build_block_system  # noqa: F401
from .faces import (GroupFaces, check_group, group_faces, has_free_face, is_connected, is_removable,  # noqa: F401
                    parallel_sets, removable_arc)
from .judges.evaluation import Mode  # noqa: F401
from .judges.rigid import BLOCK_TYPES, block_type, classify_blocks, rigid_modes  # noqa: F401
from .kinds import ModeKind  # noqa: F401
from .system import (ANGLE_TOL, BARTON_ITERATIONS, BARTON_TOL, CONTACT_GAP, DISTANCE_TOL, MIN_CONTACT,  # noqa: F401
                     BlockSystem)
