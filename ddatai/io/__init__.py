"""Readers and writers: the formats ddatai exchanges with other tools, kept apart from the
engine (the engine never imports them; they build `ddatai.Scene` objects or read `Results`).

- `ddatai.io.scenefile`: scene scripts (``build()`` in a Python file, or a DXF section);
- `ddatai.io.dxf`: sections and joint traces from CAD drawings (the ``[dxf]`` extra);
- `ddatai.io.ntdda`: ntdda's geometry and analysis files (records, text formats, readers, ntdda's
  block cutting in `geometry`, the case);
- `ddatai.io.vtk`: ParaView output (the ``[vtk]`` extra);
- `ddatai.io.checkpoint`: checkpoints of a run, to resume it.
"""
