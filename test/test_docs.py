"""The documentation stays inside the repository and true to the code.

- Every document cited in the code, config, scripts, tests and docs (``docs/model.md section 4``,
  ``test/validation/REPORT.md``) is a file of this repository, named by its path from the
  repository root (or, in a Markdown file, relative to that file), and a cited section exists as
  a numbered heading of that document. Nothing cites the background specifications (``spec/``) or
  a document outside the repository.
- Every relative link of README.md and docs/ resolves, anchors included.
- The tables of docs/ that restate the code (node parameters, bad-input kinds, model parameters,
  the muscle library) list what the code and config hold.

Each test collects every problem and fails with the whole list.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
MARKDOWN = [ROOT / "README.md", *sorted(DOCS.glob("**/*.md")), ROOT / "test/validation/REPORT.md"]
THIS_FILE = Path(__file__).resolve()


def _sources() -> list[Path]:
    """Text files whose document citations must resolve."""
    files = [
        *ROOT.glob("vm_ros/**/*.py"),
        *ROOT.glob("config/**/*.yaml"),
        *ROOT.glob("scripts/*"),
        *ROOT.glob("msg_defs/*.msg"),
        *ROOT.glob("test/**/*.py"),
        ROOT / "setup.py",
        ROOT / "Makefile",
        ROOT / "package.xml",
        *MARKDOWN,
    ]
    return sorted({f.resolve() for f in files if f.is_file() and f.resolve() != THIS_FILE})


# a document name: an optional path, then NAME.md (a Markdown link target is matched separately)
_DOC = re.compile(r"(?<![\w/.-])((?:\.{0,2}/)?(?:[\w.-]+/)*[\w.-]+\.md)\b(#[\w-]+)?")
# what follows a document name when it cites sections: "section 4", "sections 6-7", "sec. 1",
# "sections 4, 5, 8", "5b note"
_SECTIONS = re.compile(r"^,?\s*(?:sections?|sec\.)\s+((?:\d+[a-z]?(?:\s*(?:-|,|and)\s*)?)+)")
_LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
_HEADING = re.compile(r"^(#+)\s+(.*?)\s*#*\s*$", re.MULTILINE)


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def _line_of(text: str, index: int) -> int:
    return text.count("\n", 0, index) + 1


def _resolve(name: str, cited_in: Path) -> Path | None:
    """The repository file a citation names: from the root or, in Markdown, from the file's
    folder. None when it names no file of the repository."""
    candidates = [ROOT / name]
    if cited_in.suffix == ".md":
        candidates.insert(0, cited_in.parent / name)
    for candidate in candidates:
        resolved = candidate.resolve()
        if resolved.is_file() and resolved.is_relative_to(ROOT):
            return resolved
    return None


def _headings(path: Path) -> list[str]:
    return [m.group(2) for m in _HEADING.finditer(path.read_text(encoding="utf-8"))]


def _section_labels(path: Path) -> set[str]:
    """Numbered headings of a document: '## 5b. Lumped units' gives '5b' (and '5')."""
    labels = set()
    for heading in _headings(path):
        m = re.match(r"(\d+)([a-z]?)[.)]?\s", heading + " ")
        if m:
            labels.add(m.group(1) + m.group(2))
            labels.add(m.group(1))
    return labels


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    return {github_anchor(h) for h in _headings(path)}


def _cited_sections(text: str) -> list[str]:
    """Section labels cited right after a document name ("section 4", "sections 6-7")."""
    m = _SECTIONS.match(text)
    if not m:
        m = re.match(r"^\s+(\d+[a-z]?)\s+note\b", text)  # "model.md 5b note"
        return [m.group(1)] if m else []
    labels = []
    for part in re.split(r"\s*(?:,|and)\s*", m.group(1).strip()):
        if "-" in part:
            low, high = (p.strip() for p in part.split("-", 1))
            if low.isdigit() and high.isdigit():
                labels += [str(k) for k in range(int(low), int(high) + 1)]
                continue
        if part:
            labels.append(part.strip())
    return labels


def _citation_problems(path: Path) -> list[str]:
    text = path.read_text(encoding="utf-8", errors="replace")
    problems = []
    for m in _DOC.finditer(text):
        name, anchor = m.group(1), m.group(2)
        where = f"{_rel(path)}:{_line_of(text, m.start())}: {name!r}"
        if name.startswith(("spec/", "./spec/", "../spec/")) or "/spec/" in name:
            problems.append(f"{where} cites the background specification (not in the repository)")
            continue
        target = _resolve(name, path)
        if target is None:
            problems.append(
                f"{where} names no file of the repository (give its path from the "
                "repository root, e.g. docs/model.md)"
            )
            continue
        if anchor and anchor[1:] not in _anchors(target):
            problems.append(f"{where}{anchor}: no such heading in {_rel(target)}")
        missing = [
            s
            for s in _cited_sections(text[m.end() : m.end() + 60])
            if s not in _section_labels(target)
        ]
        if missing:
            problems.append(f"{where}: {_rel(target)} has no section {', '.join(missing)}")
    return problems


def test_cited_documents_are_in_the_repository():
    problems = [p for path in _sources() for p in _citation_problems(path)]
    assert not problems, (
        "document citations that do not resolve inside the repository:\n" + "\n".join(problems)
    )


def test_no_citation_of_the_background_specifications():
    pattern = re.compile(
        r"\bspec/|/work/shared|\binterfaces\.md|\bjoint_space_notes\.md"
        r"|\bstyle\.md"
    )
    problems = []
    for path in _sources():
        text = path.read_text(encoding="utf-8", errors="replace")
        problems += [
            f"{_rel(path)}:{_line_of(text, m.start())}: {m.group(0)!r}"
            for m in pattern.finditer(text)
        ]
    assert not problems, "citations of documents outside the repository:\n" + "\n".join(problems)


def test_markdown_never_calls_a_document_the_spec():
    """Prose such as "the spec's values" points at a document the reader does not have."""
    pattern = re.compile(r"\bspec(?:'s|s)?\b", re.IGNORECASE)
    problems = []
    for path in MARKDOWN:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if pattern.search(line):
                problems.append(f"{_rel(path)}:{number}: {line.strip()[:100]}")
    assert not problems, "Markdown that refers to 'the spec':\n" + "\n".join(problems)


def _link_problems(path: Path) -> list[str]:
    text = path.read_text(encoding="utf-8")
    problems = []
    for m in _LINK.finditer(text):
        target = m.group(1)
        if re.match(r"[a-z][a-z+.-]*:", target):  # http:, https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        where = f"{_rel(path)}:{_line_of(text, m.start())}: ({target})"
        resolved = (path.parent / file_part).resolve() if file_part else path
        if not resolved.is_relative_to(ROOT):
            problems.append(f"{where} leaves the repository")
        elif not resolved.exists():
            problems.append(f"{where} does not exist")
        elif anchor and resolved.suffix == ".md" and anchor not in _anchors(resolved):
            problems.append(f"{where}: no heading with anchor #{anchor} in {_rel(resolved)}")
    return problems


def test_relative_links_resolve():
    problems = [p for path in MARKDOWN for p in _link_problems(path)]
    assert not problems, "links that do not resolve:\n" + "\n".join(problems)


def test_readme_links_every_document():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    linked = {(ROOT / t.partition("#")[0]).resolve() for t in _LINK.findall(readme)}
    missing = [_rel(d) for d in sorted(DOCS.glob("**/*.md")) if d.resolve() not in linked]
    assert not missing, f"docs not linked from README.md: {missing}"


def test_the_checker_finds_what_it_must():
    """The rules above catch a bare name, a spec citation, a missing section and a bad link."""
    sample = ROOT / "vm_ros" / "sample.py"  # never written: the checks read text only
    text = (
        '"see model.md section 4", "spec/validation.md", "docs/model.md section 42", '
        '"docs/model.md sections 6-7", "docs/model.md 5b note", "test/validation/REPORT.md"'
    )
    found = []
    for m in _DOC.finditer(text):
        found.append(
            (
                m.group(1),
                _resolve(m.group(1), sample) is not None,
                _cited_sections(text[m.end() : m.end() + 60]),
            )
        )
    assert found == [
        ("model.md", False, ["4"]),
        ("spec/validation.md", False, []),
        ("docs/model.md", True, ["42"]),
        ("docs/model.md", True, ["6", "7"]),
        ("docs/model.md", True, ["5b"]),
        ("test/validation/REPORT.md", True, []),
    ]
    assert "42" not in _section_labels(DOCS / "model.md")
    assert {"1", "3", "4", "5", "5b", "6", "7", "8", "9"} <= _section_labels(DOCS / "model.md")
    assert github_anchor("10. Reconstructed values and why") == "10-reconstructed-values-and-why"
    assert github_anchor("The ROS 2 node: `muscle_node`") == "the-ros-2-node-muscle_node"


# --- tables of docs/ that restate the code -------------------------------------------------------


def _table_rows(path: Path, first_header: str) -> list[list[str]]:
    """Rows (cells stripped of backticks) of every Markdown table whose first header cell is
    ``first_header``."""
    rows, inside = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("|"):
            inside = False
            continue
        cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
        if not inside:
            inside = cells[0] == first_header
            continue
        if set(cells[0]) <= {"-", ":"}:
            continue
        rows.append(cells)
    return rows


def test_node_doc_lists_every_parameter_with_its_default():
    from vm_ros.node.params import PARAMS

    def shown(value):
        if isinstance(value, bool):
            return str(value).lower()
        if isinstance(value, (list, tuple)):
            return "[" + ", ".join(map(str, value)) + "]"
        return '""' if value == "" else str(value)

    rows = {r[0]: r for r in _table_rows(DOCS / "node.md", "name")}
    problems = [f"{p.name}: missing" for p in PARAMS if p.name not in rows]
    problems += [
        f"{p.name}: default {rows[p.name][2]} in the doc, {shown(p.default)} in the code"
        for p in PARAMS
        if p.name in rows and rows[p.name][2] != shown(p.default)
    ]
    problems += [
        f"{name}: not a parameter" for name in rows if name not in {p.name for p in PARAMS}
    ]
    assert not problems, "docs/node.md section 5 against vm_ros.node.params:\n" + "\n".join(
        problems
    )


def test_node_doc_lists_every_bad_input_kind():
    from vm_ros.node.health import ISSUE_KINDS

    rows = {r[0]: r for r in _table_rows(DOCS / "node.md", "kind")}
    problems = [f"{kind}: missing" for kind in ISSUE_KINDS if kind not in rows]
    problems += [
        f"{kind}: key {rows[kind][1]!r} in the doc, {key!r} in the code"
        for kind, (key, _) in ISSUE_KINDS.items()
        if kind in rows and rows[kind][1] != key
    ]
    problems += [f"{kind}: not an issue kind" for kind in rows if kind not in ISSUE_KINDS]
    assert not problems, "docs/node.md section 8 against vm_ros.node.health:\n" + "\n".join(
        problems
    )


def _number(text: str):
    text = text.strip()
    if text.startswith("["):
        return [float(x) for x in text.strip("[]").split(",")]
    try:
        return float(text)
    except ValueError:
        return text


def _same(doc_value: str, config_value) -> bool:
    if isinstance(config_value, bool):
        return doc_value == str(config_value).lower()
    if isinstance(config_value, (int, float)):
        return _number(doc_value) == pytest.approx(config_value, rel=1e-12)
    if isinstance(config_value, list):
        return _number(doc_value) == pytest.approx(config_value, rel=1e-12)
    return doc_value == str(config_value)


def test_model_doc_parameter_tables_match_the_config():
    config = yaml.safe_load((ROOT / "config/model.yaml").read_text(encoding="utf-8"))
    entries = {}  # (section key, name) -> config entry
    for name, entry in config["fibre_type_parameters"].items():
        entries[("fibre", name)] = entry
    for name, entry in config["generic"].items():
        entries[("generic", name)] = entry
    for scheme, table in config["recruitment"].items():
        for name, entry in table.items():
            entries[(scheme, name)] = entry
    for name, entry in config["energetics"].items():
        entries[("energetics", name)] = entry

    doc = DOCS / "model.md"
    seen, problems = set(), []

    def compare(key, values: dict, unit: str, tag: str):
        entry = entries.get(key)
        if entry is None:
            problems.append(f"{key[1]}: not in config/model.yaml ({key[0]})")
            return
        seen.add(key)
        for field, shown in values.items():
            if not _same(shown, entry[field]):
                problems.append(f"{key[1]}.{field}: {shown} in the doc, {entry[field]!r} in config")
        if unit != str(entry["unit"]):
            problems.append(f"{key[1]}: unit {unit!r} in the doc, {entry['unit']!r} in config")
        if tag != entry["tag"]:
            problems.append(f"{key[1]}: tag {tag} in the doc, {entry['tag']} in config")

    fibre_or_energetics = _table_rows(doc, "key")
    for row in fibre_or_energetics:
        name = row[0]
        if len(row) == 6:  # key | slow | fast | unit | tag | source
            section = "fibre" if ("fibre", name) in entries else "energetics"
            compare((section, name), {"slow": row[1], "fast": row[2]}, row[3], row[4])
        elif len(row) == 5:  # key | value | unit | tag | source
            section = "generic" if ("generic", name) in entries else "energetics"
            compare((section, name), {"value": row[1]}, row[2], row[3])
    for row in _table_rows(doc, "scheme"):  # scheme | key | value | unit | tag | source
        compare((row[0], row[1]), {"value": row[2]}, row[3], row[4])
    problems += [
        f"{name} ({section}): in config/model.yaml, not in docs/model.md section 8"
        for section, name in sorted(set(entries) - seen)
    ]
    assert not problems, "docs/model.md section 8 against config/model.yaml:\n" + "\n".join(
        problems
    )


def test_model_doc_muscle_table_matches_the_library():
    library = yaml.safe_load((ROOT / "config/muscles.yaml").read_text(encoding="utf-8"))["muscles"]
    rows = _table_rows(DOCS / "model.md", "muscle")
    header = [
        "mass_kg",
        "l0_m",
        "l0t_m",
        "path_length_max_m",
        "path_length_min_m",
        "fpcsa_slow",
        "ur",
    ]
    problems = [f"{name}: missing" for name in library if name not in {r[0] for r in rows}]
    for row in rows:
        entry = library.get(row[0])
        if entry is None:
            problems.append(f"{row[0]}: not in config/muscles.yaml")
            continue
        for field, shown in zip(header, row[1:8], strict=True):
            if not _same(shown, entry[field]):
                problems.append(f"{row[0]}.{field}: {shown} in the doc, {entry[field]} in config")
        f0 = 31.8e4 * entry["mass_kg"] / (1060.0 * entry["l0_m"])  # sigma m / (rho L0), SI
        if abs(float(row[8]) - f0) > 0.5:
            problems.append(f"{row[0]}: F0 {row[8]} N in the doc, {f0:.1f} N from the library")
    assert not problems, "docs/model.md muscle table against config/muscles.yaml:\n" + "\n".join(
        problems
    )
