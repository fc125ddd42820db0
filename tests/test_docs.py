"""The user-facing pages (README.md, docs/*.md) say what is true now, and hold together.

- No issue numbers and no session history: a page states the product as it is (history belongs in commits).
- Every relative link and image points at a file that exists, and every #anchor at a heading of it.
- Every `physics.md §N` the code, the tests and the pages cite is a section of docs/physics.md.
- The README's first code block is the two commands CI runs (.ci/run): `make demo`, then `make test`.
- The tables that restate the code agree with it: packages and their executables (setup.py), topics (the
  sources), the rig-data CSV columns (worm_model.rig_data.schema), the rclpy of each lock file.

Static: no ROS graph, well under a second. (The pages' computed figures: test_readme_figures.py; their command
lines: test_readme_commands.py.)
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from markdown_tables import table

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "ros_ws" / "src"
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
PACKAGES = ("worm_msgs", "worm_model", "worm_rig_driver", "torque_estimator")


def text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def prose(page: str) -> str:
    """The page without its fenced code blocks (commands and program output are quoted, not stated)."""
    return re.sub(r"^```.*?^```", "", page, flags=re.S | re.M)


def names(cell: str) -> list[str]:
    """The backticked names of a table cell."""
    return re.findall(r"`([^`]+)`", cell)


# ------------------------------------------------------------------------------------------------------------
# what is true now: no issue numbers, no session history

#: (pattern, what it catches); matched case-insensitively on each page's prose and code blocks alike
HISTORY = [
    (r"\bissues? ?#?\d+", "an issue number"),
    (r"(?<![\w&/`(\]])#\d+\b", "an issue or pull-request reference"),
    (r"\b(?:this|last|previous|earlier|another) session\b", "a session"),
    (r"\bbefore this\b|\bbefore:", "what came before"),
    (r"\b(?:previous|earlier) (?:release|version|design|graph|bench)\b", "an earlier design"),
    (r"\bthe old\b|\bused to\b|\bno longer\b|\banymore\b", "what used to be"),
    (r"\bit was \d|\bonce (?:kept|saw|was|were|had|gave)\b", "an earlier figure"),
    (r"\bnow\b", "now (as against before)"),
    (r"\bsince (?:issue|then|the last (?:release|version|session))\b", "since (a change)"),
    (r"\bleft open\b|\bwas (?:moved|renamed|replaced|removed|fixed)\b", "a change"),
]


@pytest.mark.parametrize("path", PAGES, ids=lambda p: p.name)
def test_a_page_states_the_product_as_it_is(path: Path) -> None:
    found = []
    for number, line in enumerate(text(path).splitlines(), 1):
        for pattern, what in HISTORY:
            for m in re.finditer(pattern, line, flags=re.I):
                found.append(f"{path.name}:{number}: {what}: {m.group(0)!r} in {line.strip()[:100]!r}")
    assert not found, "\n".join(found)


def test_the_history_patterns_catch_history() -> None:
    """The patterns above find what they are for, and pass the technical uses of the same words."""
    history = ["Since issue 15 the numbers are refitted", "see #12", "(before: 5 false names)",
               "a cache once kept whichever fit asked first", "(it was 2.97 / 6.96 %)", "the old graph had ten",
               "costs 0.15 cores more than it used to", "before this session", "the bench now averages"]
    technical = ["counters are totals since reset", "a frame dropped since the last telemetry",
                 "a command before HELLO", "once per gear turn", "[physics.md §2](physics.md#2-frame-of-motion)",
                 "since no estimator reads it", "[x](#3-modes)"]
    for line in history:
        assert any(re.search(p, line, flags=re.I) for p, _ in HISTORY), line
    for line in technical:
        assert not any(re.search(p, line, flags=re.I) for p, _ in HISTORY), line


# ------------------------------------------------------------------------------------------------------------
# links

def slugs(page: str) -> set[str]:
    """GitHub's anchors of a page's headings (lower case, punctuation dropped, spaces to hyphens, -1 on repeats)."""
    seen: dict[str, int] = {}
    out = set()
    for heading in re.findall(r"^#{1,6} +(.+?) *#*$", prose(page), flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def test_github_slugs() -> None:
    assert slugs("## 8. Estimating τ_d without a torque sensor (paper §3.3, Eqs 33–34)\n## The firmware in the "
                 "loop: `make fil`\n## A\n## A\n") == {"8-estimating-τ_d-without-a-torque-sensor-paper-33-eqs-3334",
                                                      "the-firmware-in-the-loop-make-fil", "a", "a-1"}


@pytest.mark.parametrize("path", PAGES, ids=lambda p: p.name)
def test_every_relative_link_points_at_a_file_and_a_heading(path: Path) -> None:
    page = prose(text(path))
    targets = re.findall(r"!?\[[^\]]*\]\(([^)\s]+)\)", page)
    bad = []
    for target in targets:
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        resolved = (path.parent / file).resolve() if file else path
        if not resolved.exists():
            bad.append(f"{target}: no such file")
        elif anchor and resolved.suffix == ".md" and anchor not in slugs(text(resolved)):
            bad.append(f"{target}: no heading #{anchor} in {resolved.relative_to(REPO)}")
    assert not bad, f"{path.name}: " + "; ".join(bad)


def test_every_page_of_docs_is_linked_from_the_readme() -> None:
    readme = text(REPO / "README.md")
    linked = {(REPO / t.partition("#")[0]).resolve() for t in re.findall(r"\]\(([^)\s#]+)[^)]*\)", readme)}
    unlinked = [p.name for p in PAGES[1:] if p.resolve() not in linked]
    assert not unlinked, unlinked


# ------------------------------------------------------------------------------------------------------------
# physics.md

def physics_sections() -> set[int]:
    return {int(n) for n in re.findall(r"^## (\d+)\. ", text(REPO / "docs" / "physics.md"), flags=re.M)}


def cited_sections(source: str) -> set[int]:
    """Section numbers cited as `physics.md §N`, `§N–M`, `section N`, `sections N-M` or `sections N, M`."""
    cited = set()
    for m in re.finditer(r"physics\.md,? (?:§ ?|sections? )(\d+(?: ?(?:[-–]|,|and) ?\d+)*)", source):
        for part in re.split(r" ?, ?| and ", m.group(1)):
            ends = [int(n) for n in re.split(r" ?[-–] ?", part)]
            cited.update(range(ends[0], ends[-1] + 1))
    return cited


def test_cited_sections() -> None:
    assert cited_sections("(physics.md sections 4-7) physics.md §8 physics.md section 3, 5 physics.md §6–7") == \
        {3, 4, 5, 6, 7, 8}


def test_every_section_of_physics_md_the_sources_cite_exists() -> None:
    sources = [*SRC.rglob("*.py"), *SRC.rglob("*.msg"), *(REPO / "tests").glob("*.py"), *PAGES]
    sources = [p for p in sources if "/build" not in str(p) and "/install" not in str(p)]
    sections = physics_sections()
    assert sections == set(range(1, 11)), sections
    missing = {}
    for path in sources:
        if path.name == "test_docs.py":
            continue
        for n in cited_sections(text(path)) - sections:
            missing.setdefault(n, []).append(str(path.relative_to(REPO)))
    assert not missing, missing
    assert cited_sections("".join(text(p) for p in sources)) >= {2, 3, 5, 6, 7, 8, 9}


# ------------------------------------------------------------------------------------------------------------
# the README's commands and tables

def test_the_first_code_block_is_what_ci_runs() -> None:
    """.ci/run runs the `make` lines of the README's first code block, in order: a newcomer's two commands."""
    block = re.search(r"^```[^\n]*\n(.*?)^```", text(REPO / "README.md"), flags=re.S | re.M).group(1)
    lines = [line for line in block.splitlines() if line.strip()]
    assert [line.split("#")[0].strip() for line in lines] == ["make demo", "make test"], lines
    assert all("#" in line for line in lines), "each command says what it does"


def console_scripts(package: str) -> set[str]:
    setup = SRC / package / "setup.py"
    if not setup.exists():
        return set()
    block = re.search(r'"console_scripts":\s*\[(.*?)\]', text(setup), flags=re.S)
    return set(re.findall(r'"(\w+) = ', block.group(1))) if block else set()


def test_the_package_table_names_every_executable() -> None:
    rows = table(text(REPO / "README.md"), "| package |")
    stated = {names(row[0])[0]: set(names(row[1])) for row in rows}
    assert set(stated) == set(PACKAGES)
    for package in PACKAGES:
        assert stated[package] == console_scripts(package), package


def source_text() -> str:
    return "".join(text(p) for pkg in PACKAGES for p in (SRC / pkg).rglob("*.py")
                   if "/test/" not in str(p) and "/build" not in str(p))


def test_the_topic_tables_name_topics_the_code_uses() -> None:
    code = source_text()
    readme = {t for row in table(text(REPO / "README.md"), "| topic |") for t in names(row[0])}
    full = {t for row in table(text(REPO / "docs" / "running.md"), "| topic |") for t in names(row[0])}
    assert readme == full, readme ^ full
    for topic in full:
        assert f'"{topic}"' in code, f"{topic}: no such topic in the sources"


def test_the_csv_schema_table_is_the_schema() -> None:
    from worm_model.rig_data.schema import OPTIONAL_COLUMNS, REQUIRED_COLUMNS
    rows = table(text(REPO / "docs" / "bags-and-tools.md"), "| column |")
    units = {"N·m": "N m", "°C": "degC"}
    stated = {names(row[0])[0]: (units.get(row[1], row[1]), row[2].startswith("required")) for row in rows}
    expected = {**{c: (u, True) for c, u in REQUIRED_COLUMNS.items()},
                **{c: (u, False) for c, u in OPTIONAL_COLUMNS.items()}}
    assert stated == expected
    assert list(stated) == [*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS]  # in the order written


def test_the_distribution_table_is_the_lock_files() -> None:
    for row in table(text(REPO / "docs" / "distributions.md"), "| `ROS_DISTRO` |"):
        lock = names(row[1])[0]
        version = re.match(r"[\d.]+", row[2]).group(0)
        assert re.search(rf"^ros-rclpy=={re.escape(version)}$", text(REPO / lock), flags=re.M), (lock, version)
