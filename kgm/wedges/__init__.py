"""kgm.wedges: the first step into 3D — wedges and key blocks of a rock slope (block theory and
vector limit equilibrium), their probabilistic study and their pictures (docs/kgm/wedge.md).

>>> import kgm, ddatai as dd
>>> j = dd.Joint(friction=30.0)
>>> w = kgm.wedge(kgm.Plane(65, 185), kgm.Plane(12, 195), 30.0,
...               [kgm.Plane(45, 105, j), kgm.Plane(70, 235, j)])
>>> w.forms, round(w.fs, 3), w.mode
(True, 1.435, 'sliding on joint 1 and joint 2')
"""
