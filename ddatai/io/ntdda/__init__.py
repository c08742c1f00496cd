"""Read ntdda ("DDA for Windows") input files and run them.

ntdda, the Berkeley C port of Shi's DC/DF programs, reads a geometry file (``.geo``: joint
lines, material lines, fixed, load, measured and hole points) and an analysis file (``.ana``:
materials, joint properties, time step, load histories), each either in Shi's original
whitespace-separated text format or in the XML "DDAML" format (docs/ntdda.md §4). The format of
each file is detected from its first characters.

>>> import ddatai as dd
>>> case = dd.read_ntdda("pushblock.geo", "pushblock.ana")     # doctest: +SKIP
>>> print(case.summary())                                       # doctest: +SKIP
>>> res = case.simulate()                                       # doctest: +SKIP
>>> from ddatai.io.ntdda import write_measured_csv
>>> write_measured_csv(res, case, "pushblock.csv")               # doctest: +SKIP

Where ntdda behaves oddly (docs/ntdda.md §3) the reader makes an
explicit choice, documented where it is made and in docs/guide/ntdda_files.md, and warns
with an `NtddaQuirkWarning` when a file relies on the odd behaviour. Settings ddatai does not
implement are ignored with an `NtddaUnsupportedWarning`. A malformed file raises
`NtddaFormatError` (a ``ValueError``) naming the file, the line (text format) or the line and
element (DDAML) and what was expected, before any simulation work.

Units: ntdda files use whatever consistent units their author chose; ddatai's SI names (m, kg,
Pa) then stand for those units. Unit mass ρ enters inertia and unit weight γ the body force,
so the effective gravity is γ/ρ (docs/method/dda.md §6.3).

Run from the command line: ``ddatai run MODEL.geo MODEL.ana --out DIR`` (`ddatai.cli`).
No Taichi at import: the solver is loaded only by `NtddaCase.simulate`.

The package: ``records`` (errors, warnings, raw file content), ``text`` (formats, tokens, DDAML),
``readers`` (the two files in either format), ``segments`` (ntdda's segment tests), ``geometry``
(ntdda's block cutting), ``placement`` (points, materials and fixed lines in the cut blocks),
``case`` (the case and its run, the measured-points CSV).
"""

from __future__ import annotations

from .records import (Format, NTDDA_ANGLE_OVERLAP, NTDDA_GRAVITY, NTDDA_NORM_SPRING_PEN,
                      NTDDA_OC_LIMIT, NTDDA_OPENCLOSE, NTDDA_OPENCRITERIA, NTDDA_PFACTOR,
                      NTDDA_SHEAR_NORM_RATIO, NtddaAnalysis, NtddaBlockMaterial, NtddaFormatError,
                      NtddaGeometry, NtddaJointMaterial, NtddaQuirkWarning, NtddaUnsupportedWarning,
                      NtddaWarning)  # noqa: F401
from .readers import read_ntdda_analysis, read_ntdda_geometry  # noqa: F401
from .case import (NtddaBlocks, NtddaCase, NtddaPoint, build_ntdda_case, cut_ntdda_geometry,
                   read_ntdda, write_measured_csv)  # noqa: F401

__all__ = ["Format", "NTDDA_ANGLE_OVERLAP", "NTDDA_GRAVITY", "NTDDA_NORM_SPRING_PEN", "NTDDA_OC_LIMIT",
           "NTDDA_OPENCLOSE", "NTDDA_OPENCRITERIA", "NTDDA_PFACTOR", "NTDDA_SHEAR_NORM_RATIO",
           "NtddaAnalysis", "NtddaBlockMaterial", "NtddaFormatError", "NtddaGeometry",
           "NtddaJointMaterial", "NtddaQuirkWarning", "NtddaUnsupportedWarning", "NtddaWarning",
           "read_ntdda_analysis", "read_ntdda_geometry", "NtddaBlocks", "NtddaCase", "NtddaPoint",
           "build_ntdda_case", "cut_ntdda_geometry", "read_ntdda", "write_measured_csv"]
