"""Every code example in the README and the user guide runs as printed.

The blocks are found in README.md, python/README.md and docs/*.md, so a new example is tested
without being listed here. By the fence's language:

- ``python``: written to a file and run as a script with this interpreter (the venv's, with the
  package installed); it must exit 0.
- ``sh``: run with ``bash -e``; it must exit 0.
- ``console``: each ``$ `` line (with its ``\\`` continuation lines) is a command, run in order
  with ``bash -e``; the lines under it are what it prints (stdout and stderr together), compared
  with ``…`` standing for anything. A command whose output is not shown is only run.
- ``toml``: a scene; written to a file, it must pass ``jello info``.
- ``rust``: a doctest of crates/jello-io (``cargo test --doc -p jello-io``): checked here only to
  be included there.
- ``text`` (or ``json``), or no language: output, formats and formulas; not run (but rustdoc
  runs a block without a language as Rust, so the pages that are doctests must say ``text``).

A block that must not run has ``<!-- no-run: the reason -->`` on the line before its fence (a
``no-run`` TOML block must still parse). Every block runs in a fresh temporary folder holding a
copy of the repository's ``examples/`` and ``python/examples/``, with the release ``jello`` and
this interpreter first on the PATH. A failure names the file and line of the block.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from conftest import REPO

PAGES = [REPO / "README.md", REPO / "python" / "README.md", *sorted((REPO / "docs").glob("*.md"))]

#: Languages whose blocks run here, are doctests elsewhere, or are never run.
RUN = {"python", "sh", "console", "toml"}
DOCTEST = {"rust"}
SHOWN = {"text", "json"}

FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>.*)$")
NO_RUN = re.compile(r"^\s*<!--\s*no-run\b(?P<rest>.*?)-->\s*$")
ANY_NO_RUN = re.compile(r"^\s*<!--\s*no-run")
SEPARATOR = "@@ jello docs: command done @@"
TIMEOUT = 300


@dataclass
class Block:
    """One fenced code block of a Markdown page."""

    page: Path
    line: int  # 1-based line of the opening fence
    lang: str
    text: str
    no_run: str | None  # the reason, when marked not to run

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def parse(page: Path) -> tuple[list[Block], list[str]]:
    """The page's fenced blocks, and what is wrong with its fences and markers."""
    lines = page.read_text(encoding="utf-8").splitlines()
    name = page.relative_to(REPO)
    blocks: list[Block] = []
    problems: list[str] = []
    used_markers: set[int] = set()
    inside: set[int] = set()  # lines within code blocks
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = m["indent"], m["fence"], m["info"].strip()
        close = re.compile(rf"^[ \t]*{re.escape(fence[0])}{{{len(fence)},}}[ \t]*$")
        j = i + 1
        while j < len(lines) and not close.match(lines[j]):
            j += 1
        if j == len(lines):
            problems.append(f"{name}:{i + 1}: a code block that is never closed")
            break
        body = [ln[len(indent):] if ln.startswith(indent) else ln.lstrip() for ln in lines[i + 1 : j]]
        lang = re.split(r"[\s,{]", info, maxsplit=1)[0].lower() if info else ""
        no_run = None
        if i > 0 and (marker := NO_RUN.match(lines[i - 1])):
            used_markers.add(i - 1)
            reason = marker["rest"].strip()
            if not reason.startswith(":") or not reason[1:].strip():
                problems.append(f"{name}:{i}: a no-run marker needs a reason: <!-- no-run: why -->")
            no_run = reason[1:].strip() or "?"
        blocks.append(Block(page, i + 1, lang, "\n".join(body) + "\n", no_run))
        inside.update(range(i, j + 1))
        i = j + 1
    for k, line in enumerate(lines):
        if ANY_NO_RUN.match(line) and k not in used_markers and k not in inside:
            problems.append(f"{name}:{k + 1}: a no-run marker must be alone on the line just before a code block's fence")
    return blocks, problems


def all_blocks() -> tuple[list[Block], list[str]]:
    blocks: list[Block] = []
    problems: list[str] = []
    for page in PAGES:
        b, p = parse(page)
        blocks += b
        problems += p
    return blocks, problems


BLOCKS, PROBLEMS = all_blocks()
RUNNABLE = [b for b in BLOCKS if b.lang in RUN and (b.no_run is None or b.lang == "toml")]


def doctest_pages() -> set[Path]:
    """The pages crates/jello-io includes as doctests (`#[doc = include_str!(…)]`)."""
    src = REPO / "crates" / "jello-io" / "src"
    lib = (src / "lib.rs").read_text(encoding="utf-8")
    return {(src / rel).resolve() for rel in re.findall(r'#\[doc = include_str!\("([^"]+)"\)\]', lib)}


def test_every_block_says_what_it_is_and_every_marker_why() -> None:
    problems = list(PROBLEMS)
    doctests = doctest_pages()
    for b in BLOCKS:
        if not b.lang:
            # Not run here; but rustdoc compiles a block without a language as Rust.
            if b.page.resolve() in doctests:
                problems.append(f"{b.where}: rustdoc runs a block without a language as Rust: write ```text")
        elif b.lang not in RUN | DOCTEST | SHOWN:
            problems.append(f"{b.where}: unknown language {b.lang!r}: use one of {sorted(RUN | DOCTEST | SHOWN)}")
        elif b.no_run is not None and b.lang not in RUN:
            problems.append(f"{b.where}: a no-run marker on a {b.lang} block, which is not run anyway")
    assert not problems, "\n".join(problems)


def test_the_pages_with_rust_blocks_are_doctests() -> None:
    included = doctest_pages()
    missing = sorted(
        {str(b.page.relative_to(REPO)) for b in BLOCKS if b.lang in DOCTEST and b.page.resolve() not in included}
    )
    assert not missing, (
        "pages with Rust blocks that `cargo test --doc -p jello-io` does not run: "
        + ", ".join(missing)
        + " (add a #[cfg(doctest)] item with #[doc = include_str!(…)] at the end of crates/jello-io/src/lib.rs)"
    )


LINK = re.compile(r"!?\[[^\]]*\]\(<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\)")
CODE_SPAN = re.compile(r"`+[^`]*`+")


def test_every_link_and_image_to_a_file_of_the_repository_finds_it() -> None:
    """Relative links and images (`[…](path)`, `![…](path)`, outside code) name files that exist."""
    missing: list[str] = []
    for page in PAGES:
        fence: str | None = None
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            m = FENCE.match(line)
            if m:
                if fence is None:
                    fence = m.group("fence")
                elif m.group("fence").startswith(fence) and not m.group("info").strip():
                    fence = None
                continue
            if fence is not None:
                continue
            for target in LINK.findall(CODE_SPAN.sub("", line)):
                path = target.split("#")[0]
                if not path or re.match(r"^[a-z][a-z0-9+.-]*:", target):
                    continue
                if not (page.parent / path).exists():
                    missing.append(f"{page.relative_to(REPO)}:{number}: {target}")
    assert not missing, "links to files that are not there:\n" + "\n".join(missing)


@pytest.fixture(scope="session")
def path_env(cli: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The environment blocks run in: `jello` (the release binary) and this Python first."""
    bin_dir = tmp_path_factory.mktemp("bin")
    (bin_dir / "jello").symlink_to(cli.resolve())
    path = os.pathsep.join([str(bin_dir), str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    return {**os.environ, "PATH": path, "MPLBACKEND": "Agg", "JELLO_DOCS_TEST": "1"}


def workdir(tmp_path: Path) -> Path:
    """A fresh folder with copies of what the examples read."""
    shutil.copytree(REPO / "examples", tmp_path / "examples")
    shutil.copytree(REPO / "python" / "examples", tmp_path / "python" / "examples")
    return tmp_path


def console_commands(block: Block) -> list[tuple[str, list[str]]]:
    """The `$ ` commands of a console block, each with the output lines shown under it."""
    commands: list[tuple[str, list[str]]] = []
    lines = block.text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("$ ") or line == "$":
            command = [line[2:]]
            while command[-1].endswith("\\") and i + 1 < len(lines):
                i += 1
                command.append(lines[i])
            commands.append(("\n".join(command), []))
        elif commands:
            commands[-1][1].append(line)
        elif line.strip():
            raise AssertionError(f"{block.where}: output before the first `$ ` command: {line!r}")
        i += 1
    assert commands, f"{block.where}: a console block with no `$ ` command"
    return commands


def matches(shown: str, printed: str) -> bool:
    """Whether `printed` is what `shown` shows, `…` standing for anything."""
    def norm(s: str) -> str:
        return "\n".join(ln.rstrip() for ln in s.strip("\n").splitlines())

    pattern = ".*?".join(re.escape(part) for part in norm(shown).split("…"))
    return re.fullmatch(pattern, norm(printed), re.DOTALL) is not None


def run(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT)


def failure(block: Block, what: str, proc: subprocess.CompletedProcess[str]) -> str:
    return (
        f"{block.where}: {what} (exit status {proc.returncode})\n"
        f"--- the block ---\n{block.text}--- stdout ---\n{proc.stdout}--- stderr ---\n{proc.stderr}"
    )


@pytest.mark.parametrize("block", RUNNABLE, ids=[b.where for b in RUNNABLE])
def test_the_example_runs_as_printed(block: Block, tmp_path: Path, path_env: dict[str, str]) -> None:
    cwd = workdir(tmp_path)
    if block.lang == "toml":
        if block.no_run is not None:
            tomllib = pytest.importorskip("tomllib")
            try:
                tomllib.loads(block.text)
            except tomllib.TOMLDecodeError as e:
                pytest.fail(f"{block.where}: a no-run TOML block that does not parse: {e}")
            return
        (cwd / "scene.toml").write_text(block.text, encoding="utf-8")
        proc = run(["jello", "info", "scene.toml"], cwd, path_env)
        assert proc.returncode == 0, failure(block, "`jello info` refuses this scene", proc)
    elif block.lang == "python":
        (cwd / "example.py").write_text(block.text, encoding="utf-8")
        proc = run([sys.executable, "example.py"], cwd, path_env)
        assert proc.returncode == 0, failure(block, "the script fails", proc)
    elif block.lang == "sh":
        script = "\n".join(ln[2:] if ln.startswith("$ ") else ln for ln in block.text.splitlines())
        (cwd / "example.sh").write_text(script + "\n", encoding="utf-8")
        proc = run(["bash", "-e", "example.sh"], cwd, path_env)
        assert proc.returncode == 0, failure(block, "a command fails", proc)
    else:
        commands = console_commands(block)
        lines = ["exec 2>&1"]
        for command, _ in commands:
            lines += [command, f"printf '\\n%s\\n' '{SEPARATOR}'"]
        (cwd / "example.sh").write_text("\n".join(lines) + "\n", encoding="utf-8")
        proc = run(["bash", "-e", "example.sh"], cwd, path_env)
        outputs = proc.stdout.split(f"\n{SEPARATOR}\n")
        done = len(outputs) - 1
        if proc.returncode != 0:
            pytest.fail(failure(block, f"`{commands[min(done, len(commands) - 1)][0]}` fails", proc))
        for (command, shown), printed in zip(commands, outputs):
            if shown and not matches("\n".join(shown), printed):
                pytest.fail(
                    f"{block.where}: `{command}` prints something else than the page shows\n"
                    f"--- shown ---\n" + "\n".join(shown) + f"\n--- printed ---\n{printed}"
                )
