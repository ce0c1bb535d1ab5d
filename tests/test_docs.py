"""The documentation stays true: links and anchors resolve, the README's command lines parse with
the real command-line parser, and the files the documentation names exist.

Fast and in-process: commands are parsed (options, types, arity), never run.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest
import typer.main

from ionav_viz.cli import app
from ionav_viz.cli.app import optional_values, root_options_first

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = [README, ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]

FENCE = re.compile(r"^\s*(```|~~~)")
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
INLINE_CODE = re.compile(r"(`+)(.+?)\1", re.DOTALL)
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")
#: Repository paths the documentation may name in backticks (checked to exist).
REPO_PATH = re.compile(r"(?<![\w./-])(?:docs|benchmarks|ionav_viz|examples|tests|\.ci)/[\w./-]*")


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def _split(text: str) -> tuple[str, list[list[str]]]:
    """Markdown -> (the prose with fenced code blocks blanked, the code blocks as lists of lines)."""
    prose, blocks, block = [], [], None
    for line in text.splitlines():
        if FENCE.match(line):
            if block is None:
                block = []
            else:
                blocks.append(block)
                block = None
            prose.append("")
        elif block is not None:
            block.append(line)
            prose.append("")
        else:
            prose.append(line)
    return "\n".join(prose), blocks


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lowercase, punctuation other than hyphens and underscores
    removed, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip())  # a link's text only
    text = re.sub(r"[^\w\- ]", "", text.lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    prose, _ = _split(path.read_text(encoding="utf-8"))
    seen: dict[str, int] = {}
    out = set()
    for line in prose.splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if m:
            base = slug(m.group(1))
            n = seen.get(base, 0)
            seen[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
    return out


def links(path: Path) -> list[str]:
    """Every link and image target in the prose (not in code blocks or code spans)."""
    prose, _ = _split(path.read_text(encoding="utf-8"))
    prose = INLINE_CODE.sub("", prose)
    return LINK.findall(prose)


def test_documentation_files_exist():
    for path in DOCS:
        assert path.is_file(), path
    assert len(DOCS) >= 5, "README.md, CONTRIBUTING.md and the docs/ pages"


def broken_links(doc: Path) -> list[str]:
    """The relative links of ``doc`` whose file or heading does not exist."""
    broken = []
    for target in links(doc):
        if SCHEME.match(target):
            continue  # a web address
        file_part, _, anchor = target.partition("#")
        dest = (doc.parent / file_part).resolve() if file_part else doc
        if not dest.exists():
            broken.append(f"{target}: no file {dest}")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            broken.append(f"{target}: no heading #{anchor} in {dest.name}")
    return broken


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_relative_links_and_anchors_resolve(doc):
    broken = broken_links(doc)
    assert not broken, f"{_rel(doc)}: " + "; ".join(broken)


def test_slugs_follow_github():
    assert slug("Errors and exit codes") == "errors-and-exit-codes"
    assert slug("Message logs: MCAP, ROS 1 bags, ROS 2 bags") == "message-logs-mcap-ros-1-bags-ros-2-bags"
    assert slug("Real GNSS outages: `--on gnss-outage`") == "real-gnss-outages---on-gnss-outage"
    assert slug("events, train, simulate") == "events-train-simulate"


def test_link_checker_finds_a_dead_link(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# Title\n\n[ok](#title) [dead](#no-such-heading) ![img](missing.png)\n\n```\n[code](nowhere.md)\n```\n")
    (tmp_path / "other.md").write_text("# Other\n\n## Same\n\n## Same\n")
    page.write_text(page.read_text() + "[a](other.md#same-1) [b](other.md#same-2) [c](https://example.org/x)\n")
    assert links(page) == ["#title", "#no-such-heading", "missing.png", "other.md#same-1", "other.md#same-2", "https://example.org/x"]
    assert anchors(page) == {"title"}
    assert [b.split(":")[0] for b in broken_links(page)] == ["#no-such-heading", "missing.png", "other.md#same-2"]


# --- command lines in the README ------------------------------------------------------------


def readme_commands() -> list[str]:
    """``ionav-viz ...`` lines of the README's code blocks, joined over trailing backslashes."""
    _, blocks = _split(README.read_text(encoding="utf-8"))
    commands = []
    for block in blocks:
        joined, pending = [], ""
        for line in block:
            if line.rstrip().endswith("\\"):
                pending += line.rstrip()[:-1] + " "
                continue
            joined.append(pending + line)
            pending = ""
        for line in joined:
            text = line.strip()
            text = text[2:] if text.startswith("$ ") else text
            if text.startswith("ionav-viz "):
                commands.append(text)
    return commands


def parse(argv: list[str]) -> tuple[str, dict]:
    """Parse a command line as ``ionav-viz`` does (root options anywhere, ``--connect`` without an
    address), down to the command's own options, without running it."""
    group = typer.main.get_command(app)
    args = optional_values(root_options_first(list(argv)))
    args = [a for a in args if a != "--print-config"]  # read before the command's options (cli/config.py), as is --config FILE
    while "--config" in args:
        at = args.index("--config")
        args = args[:at] + args[at + 2:]
    ctx = group.make_context("ionav-viz", args)
    protected = getattr(ctx, "_protected_args", None)
    if protected is None:
        protected = ctx.protected_args
    name, cmd, rest = group.resolve_command(ctx, [*protected, *ctx.args])
    sub = cmd.make_context(name, rest, parent=ctx)
    return name, sub.params


def test_the_readme_shows_commands():
    names = {command_argv(c)[0] for c in readme_commands()}
    assert len(readme_commands()) >= 10
    assert {"replay", "evaluate", "screenshot"} <= names


#: Shell syntax that ends the command's own arguments.
SHELL_ENDS = {">", ">>", "2>", "2>&1", "|", "&&", "||", ";", "&"}


def command_argv(line: str) -> list[str]:
    """``ionav-viz A B > out.json  # comment`` -> ``['A', 'B']``."""
    argv = shlex.split(line, comments=True)[1:]
    ends = [i for i, word in enumerate(argv) if word in SHELL_ENDS]
    return argv[: ends[0]] if ends else argv


@pytest.mark.parametrize("line", readme_commands())
def test_readme_command_parses(line):
    argv = command_argv(line)
    problem = None
    try:
        parse(argv)
    except Exception as exc:
        if not (type(exc).__name__ == "Exit" and getattr(exc, "exit_code", 1) == 0):  # --help, --version exit 0
            problem = exc.format_message() if hasattr(exc, "format_message") else repr(exc)
    if problem is not None:
        pytest.fail(f"README: {line!r} does not parse: {problem}", pytrace=False)


@pytest.mark.parametrize("argv", [
    ["replay", "roundabout", "--no-such-option"],
    ["no-such-command", "roundabout"],
    ["evaluate", "roundabout", "--json", "--no-such-option", "1"],
])
def test_a_bad_command_line_is_caught(argv):
    with pytest.raises(Exception) as info:
        parse(argv)
    assert hasattr(info.value, "format_message"), f"not a usage error: {info.value!r}"
    assert "no-such" in info.value.format_message().lower()


def test_shell_syntax_and_comments_are_not_arguments():
    assert command_argv("ionav-viz evaluate a b --json > out.json  # note") == ["evaluate", "a", "b", "--json"]


def test_a_good_command_line_parses_its_values():
    name, params = parse(["replay", "roundabout", "--outage", "12s", "-o", "x.rrd", "--debug"])
    assert name == "replay"
    assert params["outage"] == "12s"
    assert str(params["output"]) == "x.rrd"


def test_install_block_is_what_ci_runs():
    """The README's first code block under Install holds exactly the two set-up lines."""
    text = README.read_text(encoding="utf-8")
    section = text.split("\n## Install\n", 1)[1].split("\n## ", 1)[0]
    _, blocks = _split(section)
    assert blocks[0] == [
        'python3 -m venv .venv && . .venv/bin/activate && pip install torch==2.13.0 -e ".[test]"',
        "python -m pytest",
    ]


# --- file paths named in the documentation --------------------------------------------------


def missing_paths(text: str) -> set[str]:
    """Repository paths named in code spans and code blocks of ``text`` that do not exist."""
    prose, blocks = _split(text)
    spans = [m.group(2) for m in INLINE_CODE.finditer(prose)] + [line for block in blocks for line in block]
    return {p for span in spans for p in (m.rstrip(".,;:") for m in REPO_PATH.findall(span)) if not (ROOT / p).exists()}


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_named_repository_files_exist(doc):
    missing = missing_paths(doc.read_text(encoding="utf-8"))
    assert not missing, f"{_rel(doc)} names files that do not exist: {sorted(missing)}"


def test_path_checker_finds_a_missing_file():
    text = "See `ionav_viz/core/drive.py` and `benchmarks/no_such.py`.\n\n```bash\npython docs/gone.md\n```\n"
    assert missing_paths(text) == {"benchmarks/no_such.py", "docs/gone.md"}


# ---- help texts and the Python API point only to what exists ------------------------------------

def command_helps() -> dict[str, str]:
    """Every command's --help text (and the root's) as a user sees it, one line per option (a
    wide terminal, so no reference is wrapped)."""
    from typer.testing import CliRunner

    group = typer.main.get_command(app)
    names = group.list_commands(group.context_class(group, info_name="ionav-viz"))
    runner = CliRunner()
    helps = {}
    for name in ["", *names]:
        result = runner.invoke(app, [name, "--help"] if name else ["--help"], env={"COLUMNS": "400"})
        assert result.exit_code == 0, (name, result.output)
        helps[name or "ionav-viz"] = result.output
    return helps


def test_help_texts_name_only_existing_files_and_sections():
    text = "\n".join(command_helps().values())
    named = set(re.findall(r"(?:docs|ionav_viz)/[\w./-]*\w", text))
    assert named, "the help texts point to the docs somewhere"
    assert [p for p in named if not (ROOT / p).exists()] == []
    for doc, section in re.findall(r"'([^']+)' in (docs/[\w.-]+\.md|the README)", text):
        path = README if section == "the README" else ROOT / section
        assert slug(doc) in anchors(path), (doc, section)
    for section in re.findall(r"docs/method\.md \('([^']+)'\)", text):  # events: "docs/method.md ('Manoeuvres')"
        assert slug(section) in anchors(ROOT / "docs/method.md"), section


def test_events_help_lists_every_threshold_with_default_and_range():
    from dataclasses import asdict

    from ionav_viz.analysis.events import THRESHOLD_LIMITS, EventThresholds

    text = " ".join(command_helps()["events"].split())
    for name, default in asdict(EventThresholds()).items():
        lo, hi = THRESHOLD_LIMITS[name]
        shown = ",".join(f"{x:g}" for x in default) if isinstance(default, tuple) else f"{default:g}"
        assert f"{name} = {shown} ({lo:g} to {hi:g})" in text, name
    assert "ionav-viz events --help" in command_helps()["replay"]  # where --threshold's help sends the user


def test_everything_the_docs_call_on_the_package_is_exported():
    import ionav_viz

    called = set()
    for doc in DOCS:
        called |= set(re.findall(r"\biv\.([A-Za-z_]\w*)", doc.read_text(encoding="utf-8")))
    assert {"evaluate", "replay", "screenshot", "serve_web", "load_drive"} <= called
    assert sorted(name for name in called if not hasattr(ionav_viz, name)) == []


def test_the_images_the_docs_show_carry_the_current_numbers():
    """The hero image and the drift figure are made by docs/make_images.py, which records the
    numbers they show in docs/images.json; a change of the code's numbers makes this fail until
    the images are made again (an image showing old numbers was the README's hero once)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_images", ROOT / "docs" / "make_images.py")
    make_images = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_images)
    recorded = json.loads((ROOT / "docs" / "images.json").read_text())
    assert recorded == make_images.current_numbers(), "run 'python docs/make_images.py' and commit the images"
