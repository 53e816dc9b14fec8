"""Every command the README, experiments/README.md and ``zrp-ga --help`` show pastes into bash as
written: bash reads it without a syntax error, no word holds an unquoted glob, brace or
parenthesis (``seed=range(10)``, ``x=[1,2]``), and each argument of ``zrp-ga`` is a Hydra
override (or one of Hydra's flags), parsed by Hydra's own override parser."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.hydra_cli
ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", ROOT / "experiments" / "README.md"]
PROGRAMS = ("zrp-ga", "zrp-ga-report", "zrp-ga-compensate", "pip", "pytest", "python")
# Hydra's flags and the ones taking a value (zrp-ga --hydra-help)
FLAGS = {"-m", "--multirun", "--help", "-h", "--hydra-help", "--version", "--resolve", "--info", "-i", "--run", "-r"}
FLAGS_WITH_VALUE = {"--cfg", "-c", "--package", "-p", "--config-dir", "-cd", "--config-path", "-cp", "--config-name", "-cn",
                    "--experimental-rerun"}  # fmt: skip
PLACEHOLDERS = {"..."}  # "zrp-ga -m ... hydra/launcher=slurm": the user's own overrides
UNQUOTED = re.compile(r"[][*?(){}<>|&;`$]")


def _commands(text: str) -> list[str]:
    """The command lines of a Markdown text: the indented code blocks' lines (continued with a
    backslash), and the inline code spans, that start with one of ``PROGRAMS``; a trailing
    ``# comment`` cut."""
    found = []
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)  # fenced blocks: Python and the tree, no commands
    lines = text.splitlines()
    k = 0
    while k < len(lines):
        line = lines[k]
        if line.startswith("    ") and line.strip().split(" ")[0] in PROGRAMS:
            command = line.strip()
            while command.endswith("\\") and k + 1 < len(lines):
                k += 1
                command = command[:-1] + " " + lines[k].strip()
            found.append(command)
        k += 1
    for span in re.findall(r"`([^`]+)`", text):
        span = " ".join(span.split())
        if span.split(" ")[0] in PROGRAMS and " " in span:
            found.append(span)
    return [_uncommented(c) for c in found]


def _uncommented(command: str) -> str:
    """``command`` without its trailing comment (a ``#`` after a space, outside quotes)."""
    for m in re.finditer(r"\s#", command):
        head = command[: m.start()]
        try:
            shlex.split(head)
        except ValueError:  # the '#' is inside quotes
            continue
        return head.rstrip()
    return command


def _help_commands() -> list[str]:
    """The example commands of ``zrp-ga --help`` (conf/config.yaml's help footer), each cut
    from its description (two spaces or more)."""
    import yaml

    footer = yaml.safe_load((ROOT / "conf" / "config.yaml").read_text())["hydra"]["help"]["footer"]
    return [re.split(r"\s{2,}", line.strip())[0] for line in footer.splitlines() if line.strip().split(" ")[0] == "zrp-ga"]


def _words(command: str) -> list[str]:
    """The command's words as bash reads them, each checked for unquoted special characters."""
    lexer = shlex.shlex(command, posix=False)  # quotes kept: what is quoted is left alone
    lexer.whitespace_split = True
    for raw in lexer:
        bare = re.sub(r"'[^']*'|\"[^\"]*\"", "", raw)
        assert not UNQUOTED.search(bare.replace("&&", "")), f"{command!r}: {raw} needs quoting in bash"
    return shlex.split(command)


def overrides_of(words: list[str]) -> list[str]:
    """The Hydra overrides of a ``zrp-ga`` command's words (its flags and their values left out)."""
    out, k = [], 1
    while k < len(words):
        w = words[k]
        if w in FLAGS_WITH_VALUE:
            k += 2
            continue
        if w.startswith("-"):
            assert w in FLAGS or w.split("=")[0] in FLAGS_WITH_VALUE, f"{' '.join(words)}: unknown flag {w}"
        elif w not in PLACEHOLDERS:
            out.append(w)
        k += 1
    return out


def all_commands() -> list[str]:
    commands = [c for doc in DOCS for c in _commands(doc.read_text())] + _help_commands()
    return list(dict.fromkeys(commands))


def test_the_documents_show_commands():
    commands = all_commands()
    assert len(commands) > 40
    assert "pip install . && zrp-ga" in commands and "zrp-ga problem=multipose seed=3" in commands
    assert any(c.startswith("zrp-ga -m crossover=blend,sbx") for c in _help_commands())


@pytest.mark.parametrize("command", all_commands())
def test_each_command_pastes_into_bash_and_its_overrides_parse(command):
    from hydra.core.override_parser.overrides_parser import OverridesParser

    if shutil.which("bash"):
        check = subprocess.run(["bash", "-n", "-c", command], capture_output=True, text=True)
        assert check.returncode == 0, f"{command!r}: {check.stderr}"
    for part in command.split("&&"):
        words = _words(part.strip())
        if words and words[0] == "zrp-ga":
            overrides = overrides_of(words)
            parsed = OverridesParser.create().parse_overrides(overrides)
            assert [o.input_line for o in parsed] == overrides


@pytest.mark.parametrize("command", ["zrp-ga -m seed=range(10)", "zrp-ga -m 'x=[1,2]' y=[3,4]", "zrp-ga a=b;c", "zrp-ga x=glob(*)"])
def test_an_unquoted_command_is_caught(command):
    """The checks above on commands bash cannot take as written (a plant for each check)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    with pytest.raises(AssertionError):
        check = subprocess.run(["bash", "-n", "-c", command], capture_output=True, text=True)
        assert check.returncode == 0
        words = _words(command)
        OverridesParser.create().parse_overrides(overrides_of(words))


def test_a_bad_override_is_caught():
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import OverrideParseException

    with pytest.raises(OverrideParseException):
        OverridesParser.create().parse_overrides(overrides_of(_words("zrp-ga 'seed=range(1'")))
