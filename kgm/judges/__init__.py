"""The judges of a group (docs/kgm/architecture.md): each takes values — the block system, the
group, the blocks removed, a strength — and returns a value, never calling the search, the
studies or the command line above it.

* `kgm.judges.evaluation` – `Mode` and `Evaluation`, what every limit-equilibrium judge
  returns; the tie rule;
* `kgm.judges.limits` – the root and sign searches and their bounds;
* `kgm.judges.rigid` – the group as one rigid body (KGM);
* `kgm.judges.mechanisms` – the kinematics of Sarma mechanisms;
* `kgm.judges.sarma` – their statics, FS and critical friction (SKGM).
"""
