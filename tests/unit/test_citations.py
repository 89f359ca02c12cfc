"""Citations in code and docs point at documents of this repository, and at sections
those documents have.

Scanned: every *.py and *.md file of the repository (hidden folders, the result cache
and build output left out). Rules:

* the model contract is docs/model.md; the former outside specification is not cited;
* ``docs/<name>.md`` (or .bib) names a file that exists, and ``docs/<name>.md §N``
  (also ``§N-M``) a section ``## N. ...`` of it;
* ``[thesis]`` is the entry ``thesis2017`` of docs/references.bib;
* paths of repository files named in docs/*.md exist.
"""

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SKIP_DIRS = {"cache", "node_modules", "__pycache__", "build", "dist"}
OUTSIDE_SPEC = "model" + "-spec"  # spelled apart so this file does not cite it
DOC_CITE = re.compile(r"\bdocs/([\w./-]+?\.(?:md|bib))\b(?:,?\s*§\s*(\d+)(?:\s*[-–]\s*(\d+))?)?")
DOC_SECTION = re.compile(r"^#{2,6}\s+(\d+)\.\s", re.M)
REPO_PATH = re.compile(r"\b((?:dampersim|tests|bench|docs|examples|scripts|pages)/[\w./-]+\.(?:py|md|bib|toml|json|csv|png))")


def source_files():
    """Repository *.py and *.md files, relative to the root, sorted."""
    out = []
    for dirpath, dirnames, filenames in os.walk(ROOT):
        dirnames[:] = [d for d in dirnames if not d.startswith(".") and d not in SKIP_DIRS and not d.endswith(".egg-info")]
        for name in filenames:
            if name.endswith((".py", ".md")):
                out.append(Path(dirpath, name).relative_to(ROOT))
    return sorted(out)


def lines_of(rel):
    try:
        return (ROOT / rel).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return []


def doc_sections(rel) -> set:
    return {int(n) for n in DOC_SECTION.findall((ROOT / rel).read_text(encoding="utf-8"))}


def citation_problems(files) -> list:
    """'path:line: problem' for every citation in ``files`` that does not resolve."""
    problems = []
    sections = {}
    for rel in files:
        for no, line in enumerate(lines_of(rel), 1):
            where = f"{rel}:{no}"
            if OUTSIDE_SPEC in line:
                problems.append(f"{where}: cites {OUTSIDE_SPEC}, which is not in the repository; cite docs/model.md §N")
            for m in DOC_CITE.finditer(line):
                doc = Path("docs", m.group(1))
                if not (ROOT / doc).is_file():
                    problems.append(f"{where}: {doc} does not exist")
                    continue
                if m.group(2) is None:
                    continue
                if doc.suffix != ".md":
                    problems.append(f"{where}: {doc} has no numbered sections")
                    continue
                if doc not in sections:
                    sections[doc] = doc_sections(doc)
                for n in filter(None, (m.group(2), m.group(3))):
                    if int(n) not in sections[doc]:
                        have = ", ".join(str(s) for s in sorted(sections[doc])) or "none"
                        problems.append(f"{where}: {doc} has no section §{n} (sections: {have})")
    return problems


def test_citations_of_documents_resolve():
    files = source_files()
    assert Path("docs/model.md") in files and Path("tests/unit/test_citations.py") in files
    problems = citation_problems(files)
    assert not problems, "unresolved citations:\n" + "\n".join(problems)


def test_the_checker_finds_what_it_should(tmp_path):
    docs = "docs" + "/"  # spelled apart so that the scan of this file finds nothing
    sample = tmp_path / "sample.py"
    sample.write_text(
        f"# {OUTSIDE_SPEC} §3\n"
        f"# {docs}model.md §99 and {docs}nowhere.md\n"
        f"# {docs}model.md §3, {docs}model.md §2-6 and {docs}references.bib are fine\n"
        f"# {docs}model.md §5-77\n",
        encoding="utf-8",
    )
    problems = citation_problems([sample])
    assert len(problems) == 4, problems
    assert f"{OUTSIDE_SPEC}" in problems[0] and "§99" in problems[1] and "nowhere.md" in problems[2]
    assert "§77" in problems[3]


def test_model_doc_sections_are_numbered_in_order():
    numbers = [int(n) for n in re.findall(r"^## (\d+)\. ", (ROOT / "docs/model.md").read_text(encoding="utf-8"), re.M)]
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) >= 10


def test_thesis_is_in_the_bibliography():
    bib = (ROOT / "docs/references.bib").read_text(encoding="utf-8")
    entry = re.search(r"@phdthesis\{thesis2017,(.*?)\n\}", bib, re.S)
    assert entry, "docs/references.bib: no @phdthesis{thesis2017, ...} entry"
    fields = dict(re.findall(r"(\w+)\s*=\s*\{(.*?)\},?\n", entry.group(1) + "\n"))
    assert fields["title"] == "The Simulation and Experimental Characterisation of the Torque Converter Damper System"
    assert fields["year"] == "2017" and "University of Bath" in fields["school"] and fields["author"]


@pytest.mark.parametrize("doc", sorted(p.name for p in (ROOT / "docs").glob("*.md")))
def test_files_named_in_docs_exist(doc):
    missing = []
    for no, line in enumerate(lines_of(Path("docs", doc)), 1):
        for m in REPO_PATH.finditer(line):
            if not (ROOT / m.group(1)).exists():
                missing.append(f"docs/{doc}:{no}: {m.group(1)}")
    assert not missing, "files named in the docs do not exist:\n" + "\n".join(missing)
