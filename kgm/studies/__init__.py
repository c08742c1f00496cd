"""Studies over many analyses (docs/kgm/probabilistic.md), the top of kgm's pipeline below the
command line (docs/kgm/architecture.md):

* `kgm.studies.sampling` – the uncertain inputs: variables, their Gaussian copula, the
  per-sample seeds, the variables file;
* `kgm.studies.study` – the outcome: `Study`, one sample's `SampleRow`, the study file (write,
  append, resume, read) and the picture of the block frequencies;
* `kgm.studies.probabilistic` – `kgm.probabilistic`: samples → analysis of each → `SampleRow`
  → `Study`.

Small probabilities of failure (docs/kgm/reliability.md):

* `kgm.studies.reliability` – the estimators in standard normal space (subset simulation, FORM,
  importance sampling), pure numerics over a batch-evaluated limit state;
* `kgm.studies.estimates` – their outcome in a study's terms: the levels, the design point, and
  the estimator run again on a study file;
* `kgm.studies.rare` – ``kgm.probabilistic(..., sampling="subset" | "importance")``: the
  estimators on a study's samples;
* `kgm.studies.plots` – their pictures (the ``[plot]`` extra).

A sweep of a group's factor of safety over one input would be a fourth module here, sharing the
sample runner.
"""
