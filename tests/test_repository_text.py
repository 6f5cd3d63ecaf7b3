"""The repository speaks to its users: no numbered development stages, no tracker numbers, and no pointer to
a design document outside the repository (the design is docs/design.md).

History is told by date, version, commit or report file; a capability is named in words. The search runs
over every file git tracks or would track (untracked files that are not ignored), skipping binary files
and the machine-written JSON reports and benchmark results (their prose is checked where it is written: the
markdown beside them).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: (what it is, pattern). Each pattern is searched line by line.
PATTERNS: tuple[tuple[str, re.Pattern[str]], ...] = (
    # "session 12", "Sessions 20–22", "session-11", "sessions #3"
    ("numbered session", re.compile(r"\bsessions?[\s\-–—]*#?\s*\d", re.IGNORECASE)),
    # a stage told relative to the development process rather than by date
    ("relative session", re.compile(r"\b(?:this|next|previous|last)\s+session\b|\bearlier\s+sessions\b",
                                    re.IGNORECASE)),
    # a stage suffix in a name: "cpu-amd-epyc-s27", "-s30b", "(s28a)"
    ("stage suffix", re.compile(r"(?<![\w.])s\d{2}[a-z]?\b")),
    # "issue 17", "Issues 18 and 19", "issue #44"
    ("tracker issue", re.compile(r"\bissues?[\s\-]*#?\s*\d", re.IGNORECASE)),
    # "(#12)", "see #44", "PR #3": a bare number sign before digits, not a colour ("#333333", "#a0f") or an anchor
    ("tracker number", re.compile(r"(?:^|[\s(\[,;])#\d{1,5}(?![\w-])")),
    # the external design document: "SPEC §3.2", "SPEC.md", "../shared/SPEC.md"
    ("external design document", re.compile(r"\bSPEC\b|(?i:\bspec\.md)")),
    ("path outside the repository", re.compile(r"\.\./shared/")),
)

#: Machine output kept as data: the JSON written by the evaluation and benchmark commands (the experiments' reports
#: lie in experiments/reports/ and in each topic's own reports/ folder, experiments/<topic>/reports/).
DATA_PREFIXES = ("experiments/reports/", "bench/results/")
DATA_FOLDER = re.compile(r"^experiments/(?:[^/]+/)*reports/")
#: This file: its examples are the very text it looks for.
THIS_FILE = "tests/test_repository_text.py"


def _repository_files() -> list[str]:
    out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                         capture_output=True, check=True).stdout
    return sorted({name for name in out.decode().split("\0") if name})


def _text(path: Path) -> str | None:
    """The file's text, or None for a binary or missing file."""
    try:
        data = path.read_bytes()
    except (FileNotFoundError, IsADirectoryError):
        return None  # deleted in the working tree, not yet in the index
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def _skipped(name: str) -> bool:
    return name == THIS_FILE or (name.endswith(".json") and (name.startswith(DATA_PREFIXES)
                                                               or DATA_FOLDER.match(name) is not None))


def find_hits(text: str) -> list[tuple[int, str, str]]:
    """``(line number, what, line)`` for every pattern found in ``text``."""
    hits = []
    for number, line in enumerate(text.splitlines(), 1):
        for what, pattern in PATTERNS:
            if pattern.search(line):
                hits.append((number, what, line.strip()))
    return hits


@pytest.mark.parametrize("line", [
    "measured in session 12", "Sessions 20–22 ran on it", "The session-11 bundle", "sessions 13-21",
    "issue 44", "Issue #44", "issues 18 and 19", "fixed (#12)", "see #7 for it", "SPEC §3.2", "as SPEC §8 asks",
    "the design is in SPEC.md", "`../shared/SPEC.md`", "cpu-intel-xeon-amx-s30b.md", "first run (s28a)",
    "in this session", "Last session's run", "Earlier sessions, on the old corpus",
])
def test_patterns_catch(line):
    assert find_hits(line), line


@pytest.mark.parametrize("line", [
    "the long-term spectrum", "a specification", "MotionFeatureSpec()", "a streaming session", "ffmpeg -f s16le",
    "an earlier session of the run keeps its log", "color '#333333'", "colour #a0f", "see [Metrics](#10-metrics)",
    "paper §3.3", "supp. B.4", "corpus version 3", "commit 4c6f019", "2026-11-25", "step 12 of 30",
    "assert x == 1  # 3 seeds", "16 cosines", "s = 0.3 s", "rtf_s10", "bs16", "spec = MotionFeatureSpec()",
    "spec.dim", "MotionFeatureSpec.all_joints()",
])
def test_patterns_spare(line):
    assert not find_hits(line), line


def _repository_texts():
    """(name, text) of every repository file the checks read."""
    for name in _repository_files():
        if not _skipped(name):
            text = _text(ROOT / name)
            if text is not None:
                yield name, text


def test_no_stage_or_tracker_numbers_or_outside_references():
    """Every tracked text file: no numbered session, no issue number, no SPEC reference (file:line listed)."""
    problems = []
    for name, text in _repository_texts():
        for number, what, line in find_hits(text):
            problems.append(f"{name}:{number}: {what}: {line[:160]}")
    assert not problems, "text that refers to development stages, tracker numbers or files outside the " \
                         "repository:\n" + "\n".join(problems)


def test_design_document_is_in_the_repository():
    design = ROOT / "docs" / "design.md"
    assert design.is_file()
    titles = re.findall(r"^## \d+\. (.+)$", design.read_text(encoding="utf-8"), re.MULTILINE)
    for title in ("Audio front end", "Speech disentanglement model", "Motion representation",
                  "Gesture generation model", "Generation and editing", "Data", "Synthetic corpus", "Metrics",
                  "Conventions", "Outputs"):
        assert title in titles, title


def test_design_references_name_existing_sections():
    """Every "docs/design.md, 'Title'" in the repository names a section that exists."""
    design = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    titles = set(re.findall(r"^## \d+\. (.+)$", design, re.MULTILINE))
    reference = re.compile(r"docs/design\.md`?,\s+'([^']+)'(?:\s+and\s+'([^']+)')?")
    missing = []
    for name, text in _repository_texts():
        # references may wrap across a line break inside a docstring or a paragraph
        flat = re.sub(r"\s*\n\s*", " ", text)
        for match in reference.finditer(flat):
            for title in filter(None, match.groups()):
                if title not in titles:
                    missing.append(f"{name}: '{title}'")
    assert not missing, "references to sections docs/design.md does not have:\n" + "\n".join(missing)


def test_readme_is_short_and_opens_with_the_python_api():
    """README.md is read in ten minutes (at most 2,500 words) and its first code block is the Python API."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    words = len(readme.split())
    assert words <= 2500, f"README.md has {words} words; move details to docs/"
    first_block = re.search(r"^```[^\n]*\n(.*?)^```", readme, re.MULTILINE | re.DOTALL)
    assert first_block, "README.md has no fenced code block"
    assert "from emogesture import animate, AnimationRequest, GesturePipeline, GenerationConfig" in first_block.group(1)
