"""Every command and snippet in docs/*.md runs as written.

A doc's fenced blocks run top to bottom in one folder that holds the shared probes and the
bunny under the names the docs use (grace.hdr, ennis.hdr, bunny.obj), so a block may use what
an earlier block of the same page wrote:

- ```sh: each line starting with ``shprobe `` (backslash continuations joined, ``  #``
  comments cut) runs through the CLI entry point and must exit 0 with no traceback;
- ```console: the same for each ``$ shprobe`` line (the lines after it are its output);
- ```python: the block is executed;
- ```text: illustrative only (usage synopses with [optional] parts, sample output) — the
  one kind of block that is not run, and the docs mark it so on purpose.

A block with no language, or another language, fails the test: an unmarked block would be
skipped silently.
"""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

from shprobe.cli.main import main
from tests.conftest import data_file
from tests.tensors.tensor_support import need

DOCS = Path(__file__).resolve().parents[2] / "docs"
RUN = ("sh", "console", "python")
ILLUSTRATIVE = ("text",)

FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.S | re.M)


def blocks(page: Path) -> list[tuple[str, str, int]]:
    """(language, body, line number) of each fenced block of a page."""
    text = page.read_text(encoding="utf-8")
    return [(m.group(1).strip(), m.group(2), text.count("\n", 0, m.start()) + 1)
            for m in FENCE.finditer(text)]


def commands(lang: str, body: str) -> list[str]:
    """The shprobe command lines of a sh or console block."""
    joined = re.sub(r"\\\n\s*", " ", body)
    out = []
    for line in joined.splitlines():
        line = line.strip()
        if lang == "console":
            if not line.startswith("$ "):
                continue
            line = line[2:]
        line = re.split(r"\s{2,}#", line)[0].strip()
        if line.startswith("shprobe "):
            out.append(line)
    return out


#: The pages with a block that runs (the others hold only illustrative blocks: nothing to run)
PAGES = sorted(p for p in DOCS.glob("*.md")
               if any(lang not in ILLUSTRATIVE for lang, _, _ in blocks(p)))


def test_every_block_is_marked():
    for page in sorted(DOCS.glob("*.md")):
        for lang, _, line in blocks(page):
            assert lang in RUN + ILLUSTRATIVE, (
                f"{page.name}:{line}: a ```{lang} block — mark it sh / console / python (it "
                "runs) or text (illustrative only)")


def test_the_collection_finds_the_commands():
    langs = [lang for p in PAGES for lang, _, _ in blocks(p)]
    assert langs.count("python") >= 6 and langs.count("sh") + langs.count("console") >= 5
    cmds = [c for p in PAGES for lang, b, _ in blocks(p) if lang in ("sh", "console")
            for c in commands(lang, b)]
    assert any(c.startswith("shprobe report ") for c in cmds)
    assert any(c.startswith("shprobe demo") for c in cmds)
    # continuation lines are joined into one command
    assert any("--exr bunny.exr" in c and "--mesh bunny.obj" in c for c in cmds)


@pytest.fixture
def doc_dir(tmp_path, monkeypatch):
    for parts, name in ((("probes", "grace.hdr"), "grace.hdr"),
                        (("probes", "ennis.hdr"), "ennis.hdr"),
                        (("meshes", "bunny.obj"), "bunny.obj")):
        shutil.copy(data_file(*parts), tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.stem)
def test_page_runs_as_written(page, doc_dir, capsys):
    ran = 0
    for lang, body, line in blocks(page):
        where = f"{page.name}:{line}"
        if lang in ILLUSTRATIVE:
            continue  # marked illustrative in the doc (usage synopsis / sample output)
        if lang == "python":
            for lib in re.findall(r"^(?:import|from) (torch|jax)\b", body, re.M):
                need(lib)  # a skip naming the extra outside CI; in CI a failure
            ns: dict = {"__name__": "__doc_snippet__"}
            exec(compile(body, where, "exec"), ns)
            ran += 1
            continue
        for cmd in commands(lang, body):
            rc = main(shlex.split(cmd)[1:])
            out = capsys.readouterr()
            assert rc == 0, f"{where}: {cmd}\n{out.err}"
            assert "Traceback" not in out.err, f"{where}: {cmd}"
            ran += 1
    assert ran, f"{page.name}: no block ran"
