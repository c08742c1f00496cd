"""The fused small-model engine: a whole DDA run of a small model in one Taichi thread, many
runs side by side in one launch (docs/guide/performance.md, "The fused engine").

Today's step (`ddatai.step`) is a Python loop over phases, each a handful of NumPy calls or
Taichi launches: its cost for a model of a few blocks is its fixed overhead, not its arithmetic.
The fused engine runs the same step — Δt (§4.6), detection with the same rules
(`ddatai.kernels.detection`), the transfer of the contact memory (§3.7), the open-close
iteration with its line search and the contact law (§4, §2.8), a skyline factorisation of
the member's system, the update and the energy (§5) — inside one kernel, step after step, one
thread a member: a single run, the probes of a bisection round, the samples of a study. Each
member runs as it would alone (its own Δt, its own iterations). The NumPy path stays the
reference: tests compare the two.

- `ddatai.fused.pack`: members as flat arrays and back (NumPy; ``covers`` says what it runs);
- `ddatai.fused.engine`: launches, more room for contacts, hand-over to today's path;
- `ddatai.fused.policy`: which engine runs a simulation or a batch of judgements, and why;
- `ddatai.fused.warm`: the kernel compiled ahead of a session (``python -m ddatai.fused``);
- `ddatai.fused.kernel`, ``step``, ``iterate``, ``law``, ``system``, ``contacts``, ``blocks``: the
  Taichi functions, phase by phase.
"""
