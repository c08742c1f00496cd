"""The example section's sources: a virtual mapping table (``mapping.py`` writes
``bedding_mapping.csv``) and the CAD drawing fitted from it (``drawing.py`` writes
``section.dxf``), read by ``scenes/dxf_section.py``."""
