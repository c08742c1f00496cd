"""Documents the repository cites exist in the repository.

The code, the README, the tests, the benchmarks and the scenes cite the project's method
documents by path and section ("docs/method/dda.md §2.8"). A user has only the repository, so
every cited ``docs/…md`` path must exist, every cited section must be a heading (or numbered
paragraph) of that document, relative links between the documents must resolve, and nothing
may cite the team's internal notes (``dda-method.md``, ``kgm-method.md``, ``peers.md`` …) or a
path outside the checkout (``../shared``).
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SUFFIXES = {".py", ".md", ".toml"}
#: folders never scanned: virtual environments, caches, build and run outputs
SKIP_DIRS = {".git", ".venv", "venv", "env", "build", "dist", "out", "node_modules", "__pycache__",
             ".pytest_cache", ".hypothesis"}
#: the team's internal notes, which are not part of the repository
INTERNAL = ("dda-method.md", "kgm-method.md", "ntdda-baseline.md", "peers.md", "performance.md",
            "contact-diagnosis.md", "style.md")
INTERNAL_RE = re.compile(r"(?<![\w/.-])(" + "|".join(re.escape(n) for n in INTERNAL) + r")")
OUTSIDE_RE = re.compile(r"\.\./shared\b|shared/reference\b")
#: a docs path, optionally followed by sections: "docs/method/dda.md §2.8.1–2.8.4, §3.5"
DOC_RE = re.compile(r"(?<![\w.-])((?:\.\./)*docs/[\w./-]*?\.md)"
                    r"((?:,?\s*(?:and\s+)?§\s*[0-9][0-9a-z.]*(?:\s*[–-]\s*[0-9][0-9a-z.]*)?)*)")
#: a relative markdown link to another document: [text](path.md) or [text](path.md#anchor)
LINK_RE = re.compile(r"\]\(((?!https?:|mailto:)[^)\s#]+\.md)(?:#[^)]*)?\)")
#: in a document under docs/: "dda.md §5.1" or "../kgm/method.md §6.1" (a sibling's sections)
SIBLING_RE = re.compile(r"(?<![\w/.-])((?:\.\./)*(?:[\w-]+/)*[\w-]+\.md)\)?"
                        r"((?:,?\s*(?:and\s+)?§\s*[0-9][0-9a-z.]*(?:\s*[–-]\s*[0-9][0-9a-z.]*)?)+)")
SECTION_RE = re.compile(r"§\s*([0-9][0-9a-z.]*)")
HEADING_RE = re.compile(r"^(?:#{1,6}\s+)?([0-9]+[a-z]?(?:\.[0-9]+)*)[.\s]")


def _files() -> list[Path]:
    out = []
    for path in ROOT.rglob("*"):
        rel = path.relative_to(ROOT)
        # hidden folders (.git, .venv, CI's .ci-venv, caches) and anything installed
        if any(part in SKIP_DIRS or part.endswith(".egg-info") or part.startswith(".")
               or part == "site-packages" for part in rel.parts[:-1]):
            continue
        if path.suffix in SUFFIXES and path.is_file():
            out.append(path)
    return sorted(out)


FILES = _files()


@lru_cache(maxsize=None)
def _sections(doc: Path) -> frozenset:
    """Section numbers of a document: its numbered headings and numbered paragraphs."""
    found = set()
    in_code = False
    for line in doc.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
            continue
        if in_code:
            continue
        m = HEADING_RE.match(line)
        if m and (line.startswith("#") or re.match(r"^[0-9]+\.[0-9]+\s+\*\*", line)):
            found.add(m.group(1))
    return frozenset(found)


def _cited_sections(text: str) -> list[str]:
    out = []
    for m in SECTION_RE.finditer(text):
        out.append(m.group(1).rstrip("."))
    # the other end of a range "§2.8.1–2.8.4"
    for m in re.finditer(r"§\s*[0-9][0-9a-z.]*\s*[–-]\s*([0-9][0-9a-z.]*)", text):
        out.append(m.group(1).rstrip("."))
    return out


def _lines(path: Path):
    for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
        yield number, line


def _check_doc(doc: Path, sections: str, where: str, problems: list) -> None:
    if not doc.is_file():
        problems.append(f"{where}: {doc.relative_to(ROOT) if doc.is_relative_to(ROOT) else doc} "
                        f"does not exist")
        return
    have = _sections(doc)
    for s in _cited_sections(sections):
        if s not in have:
            problems.append(f"{where}: {doc.relative_to(ROOT)} has no section §{s}")


def test_files_are_scanned():
    names = {p.relative_to(ROOT).as_posix() for p in FILES}
    assert "README.md" in names and "ddatai/step.py" in names and "docs/method/dda.md" in names
    assert not any("site-packages" in n for n in names)


def test_no_internal_documents_cited():
    """Nothing cites the team's internal notes or a folder outside the repository."""
    problems = []
    for path in FILES:
        if path == Path(__file__).resolve():
            continue
        for number, line in _lines(path):
            for m in INTERNAL_RE.finditer(line):
                problems.append(f"{path.relative_to(ROOT)}:{number}: cites {m.group(1)}")
            if OUTSIDE_RE.search(line):
                problems.append(f"{path.relative_to(ROOT)}:{number}: points outside the repository")
    assert not problems, "internal documents cited:\n" + "\n".join(problems)


def test_cited_docs_and_sections_exist():
    """Every docs/…md path cited anywhere exists, with the sections cited."""
    problems = []
    for path in FILES:
        if path == Path(__file__).resolve():
            continue
        for number, line in _lines(path):
            for m in DOC_RE.finditer(line):
                cited = m.group(1)
                doc = (path.parent / cited).resolve() if cited.startswith("..") else ROOT / cited
                _check_doc(doc, m.group(2), f"{path.relative_to(ROOT)}:{number}", problems)
    assert not problems, "missing documents or sections:\n" + "\n".join(problems)


def test_links_between_documents_resolve():
    """Relative links in the Markdown files, and sibling citations inside docs/, resolve."""
    problems = []
    for path in FILES:
        if path.suffix != ".md":
            continue
        in_docs = path.relative_to(ROOT).parts[0] == "docs"
        for number, line in _lines(path):
            where = f"{path.relative_to(ROOT)}:{number}"
            for m in LINK_RE.finditer(line):
                target = (path.parent / m.group(1)).resolve()
                if not target.is_file():
                    problems.append(f"{where}: link to {m.group(1)} does not resolve")
            if in_docs:
                for m in SIBLING_RE.finditer(line):
                    cited = m.group(1)
                    if cited.startswith("docs/"):
                        continue  # checked by test_cited_docs_and_sections_exist
                    _check_doc((path.parent / cited).resolve(), m.group(2), where, problems)
    assert not problems, "unresolved links:\n" + "\n".join(problems)


def test_section_parser():
    assert _cited_sections("§2.8.1–2.8.4, §3.5") == ["2.8.1", "3.5", "2.8.4"]
    assert _cited_sections("§7d.") == ["7d"]
    dda = _sections(ROOT / "docs" / "method" / "dda.md")
    assert {"0", "1.2", "2.8.1", "3.7", "4.2", "5.3", "7d", "8.12", "11"} <= dda


def test_readme_mentions_no_issue_numbers():
    """The README describes the software, not the tracker: no "issue 12" or "#12"."""
    problems = [f"README.md:{n}: {line.strip()[:80]}" for n, line in _lines(ROOT / "README.md")
                if re.search(r"\bissues?\s*(?:no\.?\s*)?#?\d+|(?<![\w&])#\d+\b", line, re.IGNORECASE)]
    assert not problems, "issue numbers in the README:\n" + "\n".join(problems)
