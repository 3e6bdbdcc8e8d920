"""docs/*.md match the code (issue 21, item 8): every Python import shown in the docs runs, every
```python block compiles, and every `atlasgen ...` command line in a code block names a real command
and only options that command has (click's own parameter table, without running the command)."""

from __future__ import annotations

import ast
import re
import shlex
from pathlib import Path

import click
import pytest

from atlasgen.cli.main import app

DOCS = sorted((Path(__file__).resolve().parents[1] / "docs").glob("*.md"))
FENCE = re.compile(r"^[ \t]*```(\w*)\n(.*?)^[ \t]*```", re.S | re.M)


def _blocks(language=None):
    for doc in DOCS:
        for lang, body in FENCE.findall(doc.read_text(encoding="utf-8")):
            if language is None or lang == language:
                yield doc.name, lang, body


def _imports():
    """Every ``from atlasgen... import ...`` / ``import atlasgen...`` statement in the docs: in Python
    blocks (parsed) and on lines of their own elsewhere."""
    found = set()
    for name, lang, body in _blocks():
        if lang == "python":
            for node in ast.walk(ast.parse(body)):
                if isinstance(node, (ast.Import, ast.ImportFrom)) and ast.unparse(node).split()[1].startswith("atlasgen"):
                    found.add((name, ast.unparse(node)))
    for doc in DOCS:
        for line in doc.read_text(encoding="utf-8").splitlines():
            if re.match(r"^(from atlasgen[\w.]* import [\w, ]+|import atlasgen[\w.]*)$", line.strip()):
                found.add((doc.name, line.strip()))
    return sorted(found)


def _command_lines():
    """``atlasgen ...`` lines of the docs' plain and indented code blocks and inline code, continuation lines joined."""
    out = []
    for name, lang, body in _blocks():
        if lang not in ("", "sh", "bash", "console", "shell"):
            continue
        for line in body.replace("\\\n", " ").splitlines():
            text = line.strip().removeprefix("$ ")
            if text.startswith("atlasgen ") or text == "atlasgen":
                out.append((name, text))
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8").replace("\\\n", " ")
        indented = re.findall(r"^    (atlasgen [^\n]*)", text, re.M)  # Markdown's indented code blocks
        spans = re.findall(r"`(atlasgen [^`<]+)`", text)  # inline code, less templates such as `atlasgen <version>`
        out += [(doc.name, " ".join(x.split())) for x in indented + spans]
    return sorted(set(out))


def test_the_docs_show_imports_blocks_and_commands():
    assert any("evaluate_separable" in statement for _, statement in _imports())
    assert len(list(_blocks("python"))) >= 3 and len(_command_lines()) >= 3


@pytest.mark.parametrize("doc, statement", _imports())
def test_every_documented_import_runs(doc, statement):
    exec(compile(statement, doc, "exec"), {})


@pytest.mark.parametrize("doc, body", [(d, b) for d, _, b in _blocks("python")])
def test_every_python_block_compiles(doc, body):
    compile(body, doc, "exec")


def _options(command: click.Command) -> set:
    names = {"--help", "-h"}
    for param in command.params:
        names.update(getattr(param, "opts", ()))
        names.update(getattr(param, "secondary_opts", ()))
    return names


@pytest.mark.parametrize("doc, line", _command_lines())
def test_every_documented_command_parses(doc, line):
    """The words up to the first option or argument name a command (lazy ones imported as `atlasgen`
    would), and every option the line shows is one of that command's (its synopsis's brackets aside)."""
    words = shlex.split(re.sub(r"[\[\]]", " ", line.split("#")[0]).replace("|", " "))
    command, ctx = app, click.Context(app, info_name="atlasgen")
    rest = words[1:]
    while rest and isinstance(command, click.Group) and rest[0] in command.list_commands(ctx):
        command = command.get_command(ctx, rest[0])
        ctx = click.Context(command, parent=ctx, info_name=rest[0])
        rest = rest[1:]
    assert command is not app or not rest or rest[0].startswith("-"), f"{doc}: unknown command in {line!r}"
    known = _options(command) | (_options(app) if command is not app else set())
    for word in rest:
        option = word.split("=")[0]
        if re.match(r"^--?[A-Za-z]", option):
            assert option in known, f"{doc}: {line!r}: {option} is not an option of {ctx.command_path}"
