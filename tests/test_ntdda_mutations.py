"""Mutated real ntdda input files (truncated, counts changed, numbers replaced by NaN, inf or
1e308, lines swapped or duplicated, XML broken) never crash, hang or exhaust memory: the
readers either return a scene that builds, or raise `NtddaFormatError` / `ValueError` naming
the file."""

from __future__ import annotations

import re
import time
import warnings

import pytest

hypothesis = pytest.importorskip("hypothesis", reason="the mutation suite needs hypothesis (pip install -e '.[test]')")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import ddatai as dd  # noqa: E402
from ddatai.io.ntdda import NtddaFormatError  # noqa: E402
from test_ntdda import DATA  # noqa: E402

PAIRS = [("circleslope.geo", "circleslope.ana"), ("pushblock.geo", "pushblock.ana")]
NUMBER = re.compile(r"-?\d+(\.\d+)?([eE][-+]?\d+)?")
REPLACEMENTS = ["nan", "inf", "-inf", "1e308", "-1e308", "0", "-1", "1e-308", "99999999", "3.5"]

pytestmark = pytest.mark.skipif(not (DATA / "circleslope.geo").exists(),
                                reason=f"ntdda example files not found in {DATA} (set DDATAI_NTDDA_DATA)")


@st.composite
def mutations(draw):
    geo, ana = draw(st.sampled_from(PAIRS))
    which = draw(st.sampled_from(["geo", "ana"]))
    text = (DATA / (geo if which == "geo" else ana)).read_text()
    lines = text.splitlines()
    kind = draw(st.sampled_from(["truncate", "number", "swap", "duplicate", "delete", "xml"]))
    if kind == "truncate":
        cut = draw(st.integers(0, len(text) - 1))
        text = text[:cut]
    elif kind == "number":
        spans = [m.span() for m in NUMBER.finditer(text)]
        for _ in range(draw(st.integers(1, 3))):
            a, b = spans[draw(st.integers(0, len(spans) - 1))]
            text = text[:a] + draw(st.sampled_from(REPLACEMENTS)).ljust(b - a)[:max(b - a, 1)] + text[b:]
            spans = [m.span() for m in NUMBER.finditer(text)]
    elif kind in ("swap", "duplicate", "delete"):
        i = draw(st.integers(0, len(lines) - 1))
        j = draw(st.integers(0, len(lines) - 1))
        if kind == "swap":
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == "duplicate":
            lines.insert(j, lines[i])
        else:
            del lines[i]
        text = "\n".join(lines) + "\n"
    else:  # break the markup: drop or insert a bracket
        pos = draw(st.integers(0, len(text) - 1))
        text = text[:pos] + draw(st.sampled_from(["<", ">", "</", "\"", ""])) + text[pos + 1:]
    return geo, ana, which, text


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(mutations())
def test_mutated_ntdda_files_are_read_or_refused(tmp_path_factory, case):
    geo, ana, which, text = case
    folder = tmp_path_factory.mktemp("mutated")
    paths = {"geo": DATA / geo, "ana": DATA / ana}
    paths[which] = folder / (geo if which == "geo" else ana)
    paths[which].write_text(text)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            case_ = dd.read_ntdda(paths["geo"], paths["ana"])
            dd.build_model(case_.scene, case_.params)
    except NtddaFormatError as err:
        assert paths[which].name in str(err)
    except ValueError as err:  # refused by the scene or model checks
        assert str(err)
    assert time.perf_counter() - t0 < 30.0, "reading took more than 30 s"
