"""The judges of a group (docs/kgm/architecture.md): each takes values — the block system or the
`kgm.build.Problem`, the group, the blocks removed, a strength — and returns a value, never
calling the search, the analyses, the studies or the command line above it.

* `kgm.judges.evaluation` – `Mode` and `Evaluation`, what every limit-equilibrium judge
  returns; the tie rule;
* `kgm.judges.limits` – the root and sign searches and their bounds;
* `kgm.judges.rigid` – the group as one rigid body (KGM), block types;
* `kgm.judges.mechanisms` – the kinematics of Sarma mechanisms;
* `kgm.judges.sarma` – their statics, FS and critical friction (SKGM);
* `kgm.judges.toppling` – the Goodman–Bray recursion of a toppling row;
* `kgm.judges.run` – one DDA run of a group and its verdict (`RunPlan`, `run_judgement`);
* `kgm.judges.fused` – many DDA runs in one launch of the fused engine, one thread each;
* `kgm.judges.batch` – many DDA runs side by side in one model (or on the fused engine);
* `kgm.judges.dda` – the factor of safety and critical friction on DDA verdicts.
"""
