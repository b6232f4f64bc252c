"""The walkthrough of the plug-in example in ``docs/plugins.md`` (its last section, from the
heading "## A real plug-in" to the end) shows the example's own code: each fenced ``python``
block is a contiguous run of whole lines of ``examples/ukf_plugin/navsim_ukf.py`` and each
``toml`` block one of ``examples/ukf_plugin/pyproject.toml`` (lines compared with trailing
whitespace stripped, exact otherwise), there is at least one ``python`` block, and the
``python`` blocks together show the ``def`` line of every method of ``ErrorStateUKF``."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "plugins.md"
EXAMPLE = ROOT / "examples" / "ukf_plugin"
HEADING = "## A real plug-in"


def lines_of(path: Path) -> list[str]:
    return [line.rstrip() for line in path.read_text().splitlines()]


def section_blocks() -> list[tuple[str, int, list[str]]]:
    """``(language, line number in the doc of the opening fence, lines)`` of each fenced block
    of the section."""
    doc = lines_of(DOC)
    starts = [i for i, line in enumerate(doc) if line.startswith(HEADING)]
    assert starts, f"{DOC.name}: no heading starting with {HEADING!r}"
    blocks, i = [], starts[0] + 1
    while i < len(doc):
        if doc[i].startswith("```"):
            lang, first = doc[i][3:].strip(), i
            end = next((k for k in range(i + 1, len(doc)) if doc[k].strip() == "```"), None)
            assert end is not None, f"{DOC.name}:{first + 1}: the ```{lang} block is not closed"
            blocks.append((lang, first + 1, doc[i + 1:end]))
            i = end
        i += 1
    return blocks


def matches(block: list[str], source: list[str]) -> list[int]:
    """The indices of ``source`` at which ``block`` appears as a contiguous run of lines."""
    n = len(block)
    return [i for i in range(len(source) - n + 1) if source[i:i + n] == block] if n else []


def mismatch(block: list[str], source: list[str]) -> str:
    """Where the block departs from the file: its first line that does not follow, anywhere in
    the file, the lines of the block before it."""
    best = 0
    for i in range(len(source)):
        k = 0
        while k < len(block) and i + k < len(source) and source[i + k] == block[k]:
            k += 1
        best = max(best, k)
    if not block:
        return "the block is empty"
    if best == 0:
        return f"its line 1 ({block[0]!r}) is not a line of the file"
    return f"its line {best + 1} ({block[best]!r}) does not follow its lines 1-{best} in the file"


def check_blocks(lang: str, path: Path) -> list[tuple[int, list[str], list[int]]]:
    """Every ``lang`` block of the section with where it stands in ``path``; fails naming each
    block that is not an excerpt of it."""
    source = lines_of(path)
    found, failures = [], []
    for number, (_, line, block) in enumerate(b for b in section_blocks() if b[0] == lang):
        at = matches(block, source)
        if not at:
            head = block[0] if block else ""
            failures.append(f"```{lang} block {number + 1} (docs/plugins.md line {line}, starting {head!r}) "
                            f"is not a contiguous excerpt of {path.relative_to(ROOT)}: {mismatch(block, source)}")
        found.append((line, block, at))
    assert not failures, "\n".join(failures)
    return found


def test_the_section_has_python_blocks():
    assert any(lang == "python" for lang, _, _ in section_blocks()), \
        f"{DOC.name}: no ```python block after {HEADING!r}"


def test_the_python_blocks_are_excerpts_of_navsim_ukf():
    check_blocks("python", EXAMPLE / "navsim_ukf.py")


def test_the_toml_blocks_are_excerpts_of_pyproject():
    check_blocks("toml", EXAMPLE / "pyproject.toml")


def test_the_python_blocks_show_every_method_of_the_class():
    path = EXAMPLE / "navsim_ukf.py"
    tree = ast.parse(path.read_text())
    cls = next((node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "ErrorStateUKF"), None)
    if cls is None:
        pytest.fail(f"{path.relative_to(ROOT)} has no class ErrorStateUKF")
    defs = {node.lineno - 1: node.name for node in cls.body
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))}
    assert defs, "ErrorStateUKF has no methods"
    shown = {i + k for _, block, at in check_blocks("python", path) for i in at for k in range(len(block))}
    missing = [f"ErrorStateUKF.{name} (navsim_ukf.py line {i + 1})" for i, name in sorted(defs.items()) if i not in shown]
    assert not missing, "no ```python block of docs/plugins.md shows the def line of " + ", ".join(missing)
