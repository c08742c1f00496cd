"""Former home of many DDA judgements in one run, now `kgm.judges.batch`
(docs/kgm/architecture.md): its names stay importable from here for one release."""

from .judges.batch import Member, judge_many, judge_members  # noqa: F401
