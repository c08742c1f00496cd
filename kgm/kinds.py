"""The vocabulary of kgm: the one definition of the method names, the kinds of failure mode, the
states of a toppling row's blocks, how a DDA run ended and the sampling schemes of a study
(docs/kgm/architecture.md), as `ddatai.layout` is the one definition of the contact states.

Every word is a ``str`` enum, so the strings of the public API stay valid and the old
comparisons stay true: ``Method("sarma") == "sarma"``, ``kgm.analyze(scene, method="dda")``.
Everything else in kgm compares members, never string literals (a test checks).
"""

from __future__ import annotations

from enum import Enum


class _Word(str, Enum):
    """A str enum that prints as its value (``f"{Method.SARMA}"`` is ``sarma``), as
    `enum.StrEnum` does from Python 3.11 on."""

    __str__ = str.__str__
    __format__ = str.__format__


class Method(_Word):
    """How a group is judged (docs/kgm/method.md §4–6)."""

    RIGID = "rigid"   # the group glued into one rigid body, limit equilibrium (KGM)
    SARMA = "sarma"   # blocks slide on their own bases and shear their shared joints (SKGM)
    DDA = "dda"       # the group simulated with ddatai on its real joint geometry

    @classmethod
    def of(cls, name) -> "Method":
        """The method named ``name``; ValueError naming the three otherwise."""
        try:
            return cls(name)
        except (ValueError, TypeError):
            raise ValueError(f"unknown method {name!r}: expected 'rigid', 'sarma' or 'dda'") from None

    def screened_by(self, screening: "Method") -> "Method":
        """The limit-equilibrium method that proposes the candidate groups: the method itself,
        or for DDA the screening method (`kgm.Settings.screening`; a DDA run per candidate
        merge would be far too slow, docs/kgm/method.md §3.6)."""
        return Method(screening) if self is Method.DDA else self


#: the limit-equilibrium methods (those that can screen candidates for DDA)
LIMIT_EQUILIBRIUM = (Method.RIGID, Method.SARMA)
#: every method, in the order of the paper's table
METHODS = tuple(Method)
#: the method names as the command line and error messages list them
METHOD_NAMES = tuple(m.value for m in Method)


class ModeKind(str, Enum):
    """How a block or group fails (docs/kgm/method.md §2.4, §5.2)."""

    NONE = "none"            # no admissible mode: stable by geometry (type III)
    LIFTING = "lifting"      # moves away from every contact (free fall)
    SLIDING = "sliding"      # rigid translation on one face (parallel faces pooled)
    ROTATION = "rotation"    # rigid rotation about a vertex (toppling), or turning on two sliding points
    SARMA = "sarma"          # blocks translate separately, shearing their shared joints
    TOPPLING = "toppling"    # a row of blocks toppling and sliding on their own bases
                             # (Goodman & Bray 1976, kgm.judges.toppling)


class BlockState(str, Enum):
    """How one block of a toppling row behaves in the Goodman–Bray recursion."""

    STABLE = "stable"
    TOPPLING = "toppling"
    SLIDING = "sliding"


class RunEnd(_Word):
    """How a DDA judgement's run ended (`kgm.DdaJudgement.end`; its ``note`` says it in words)."""

    DURATION = "ran its duration"          # simulated the whole time T
    AT_REST = "at rest"                    # every free block at rest: stopped as stable
    STOPPED_EARLY = "stopped early"        # moved past DdaSettings.stop_ratio·δ: unstable
    DIVERGED = "diverged after failing"    # the simulation failed after the group had failed

    def note(self, cause: str = "") -> str:
        """`kgm.DdaJudgement.note` of a run that ended so: '' for a whole run, the cause after
        the words for a divergence."""
        if self is RunEnd.DURATION:
            return ""
        return f"{self.value}: {cause}" if self is RunEnd.DIVERGED else self.value


class Sampling(_Word):
    """How a probabilistic study draws its samples (docs/kgm/probabilistic.md,
    docs/kgm/reliability.md)."""

    MONTE_CARLO = "monte-carlo"           # independent uniform numbers
    LATIN_HYPERCUBE = "latin-hypercube"   # one sample in each of n equal-probability strata
    SUBSET = "subset"                     # subset simulation (Au & Beck 2001): small P_f
    IMPORTANCE = "importance"             # FORM's design point, then importance sampling there


#: the sampling names as the command line and error messages list them
SAMPLINGS = tuple(s.value for s in Sampling)
#: the samplings drawn before any work, all at once (`kgm.sample_variables`)
DRAWN_SAMPLINGS = (Sampling.MONTE_CARLO, Sampling.LATIN_HYPERCUBE)
#: the samplings whose estimator chooses each batch from the results of the ones before
#: (`kgm.studies.rare`)
RARE_SAMPLINGS = (Sampling.SUBSET, Sampling.IMPORTANCE)
