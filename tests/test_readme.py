"""The README's commands are the CLI's: every `facepuppet CMD --option` it shows is an option of CMD."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from facepuppet.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]


def _readme_commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    out = []
    for block in re.findall(r"```sh\n(.*?)```", text, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("#", 1)[0].strip()
            m = re.search(r"(?:^|\s|/)facepuppet (\w[\w-]*)(.*)$", line)
            if m:
                out.append([m.group(1), *shlex.split(m.group(2).replace("[", " ").replace("]", " ")
                                                    .replace("|", " "))])
    return out


COMMANDS = _readme_commands()


def _subparsers():
    parser = build_parser()
    action = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")  # noqa: SLF001
    return action.choices


def test_the_readme_shows_every_command():
    shown = {c[0] for c in COMMANDS}
    assert set(_subparsers()) <= shown, set(_subparsers()) - shown


@pytest.mark.parametrize("words", COMMANDS, ids=[" ".join(c)[:60] for c in COMMANDS])
def test_readme_options_exist(words):
    sub = _subparsers()
    assert words[0] in sub, f"README names a command the CLI lacks: {words[0]}"
    known = {s for a in sub[words[0]]._actions for s in a.option_strings}  # noqa: SLF001
    used = {w.split("=", 1)[0] for w in words[1:] if w.startswith("--")}
    assert used <= known, f"facepuppet {words[0]}: README uses {sorted(used - known)}"
