"""Experiment files: a command and its options in a TOML file, run with ``ionav-viz run FILE`` or
given to any command with ``--config FILE``; ``--print-config`` writes any command's effective
configuration in that form.

An experiment file::

    # evaluate two drives on 10 and 30 s outages, the IDNN and the INS DR only
    command = "evaluate"
    drives = ["V-Vw8", "roundabout"]      # the command's arguments ("arguments" works for any command)
    outage = "10s,30s"                     # any option of the command: its long name without "--"
    estimators = ["ins", "idnn"]          # a list: comma-joined, or repeated for a repeatable option
    warm-up = "30s"                        # dashes or underscores alike
    json = true                            # a flag: true gives it, false leaves it out (or gives --no-FLAG)

Options given on the command line as well win over the file's; drives given there replace the
file's. Every key is checked against the command's options before anything runs: an unknown key,
or a value of the wrong kind, is one line naming the file, the line and the key.
"""

from __future__ import annotations

import math
import re
import sys
import tomllib
from dataclasses import dataclass
from datetime import date, datetime, time
from pathlib import Path
from typing import Any

from ..core.errors import InputError

#: The option that reads an experiment file into any command, and the one that prints the effective one.
CONFIG_OPTION = "--config"
PRINT_CONFIG_OPTION = "--print-config"
#: Keys with a meaning of their own (not options).
COMMAND_KEY, ARGUMENTS_KEY = "command", "arguments"
#: An experiment file larger than this is not one (a mistaken path to a log, say).
MAX_CONFIG_BYTES = 1_000_000
#: Options that say how loudly a command runs, never part of its configuration.
NOT_CONFIGURATION = frozenset(("--help", CONFIG_OPTION, PRINT_CONFIG_OPTION))
#: Options that say where and how loudly the work runs, not what it computes: printed by
#: ``--print-config`` and taken from files, but left out of the configuration a report carries, so
#: that a fleet's report is byte for byte the same whatever the workers.
HOW_IT_RUNS = frozenset(("--workers", "--cluster", "--quiet", "--fail-fast"))


@dataclass(frozen=True)
class ConfigFile:
    """An experiment file, read and checked for TOML: its ``command`` (None: not given), its
    arguments (None: not given), its options by key, and each key's line (for errors)."""

    path: Path
    command: str | None
    arguments: list[str] | None
    options: dict[str, Any]
    lines: dict[str, int]

    def where(self, key: str) -> str:
        """``FILE line N (KEY)``: where a key was read, for errors."""
        line = self.lines.get(key)
        return f"{self.path}" + (f" line {line}" if line else "") + f" ({key})"


def read_config(path: str | Path) -> ConfigFile:
    """Read an experiment file: its TOML parsed, its ``command`` and arguments taken out, every other
    top-level key an option. InputError (one line, naming the file and the line) when it cannot
    be read, is not TOML, or holds a table where options go."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            data = f.read(MAX_CONFIG_BYTES + 1)
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, not an experiment file", "give a .toml file", param="config") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the experiment file ({exc.strerror or exc})", "check the path",
                         param="config") from None
    if len(data) > MAX_CONFIG_BYTES:
        raise InputError(f"{path}: larger than {MAX_CONFIG_BYTES // 1_000_000} MB: not an experiment file",
                         "give a .toml file", param="config")
    try:
        text = data.decode("utf-8")
        table = tomllib.loads(text)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text: not an experiment file", "give a .toml file",
                         param="config") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}", "see 'Experiment files' in the README for the form",
                         param="config") from None
    lines = _key_lines(text, table)
    command = table.pop(COMMAND_KEY, None)
    if command is not None and not isinstance(command, str):
        raise InputError(f"{path} line {lines.get(COMMAND_KEY, '?')}: command = {command!r} is not a command's name",
                         'e.g. command = "evaluate"', param="config")
    arguments = _arguments(path, table, lines)
    for key, value in table.items():
        if isinstance(value, dict):
            raise InputError(f"{path} line {lines.get(key, '?')}: [{key}] is a table; options are top-level keys",
                             f"write the options of [{key}] at the top of the file, e.g. outage = \"10s\"",
                             param="config")
    return ConfigFile(path, command, arguments, table, lines)


def _arguments(path: Path, table: dict[str, Any], lines: dict[str, int]) -> list[str] | None:
    """The arguments under ``arguments``, or under the command's own argument's name (checked
    against the command later): a string or a list of strings."""
    value = table.pop(ARGUMENTS_KEY, None)
    if value is None:
        return None
    items = value if isinstance(value, list) else [value]
    if not all(isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in items):
        raise InputError(f"{path} line {lines.get(ARGUMENTS_KEY, '?')}: arguments = {value!r} is not a list of names",
                         'e.g. arguments = ["V-Vw8", "drives/"]', param="config")
    return [str(v) for v in items]


def _key_lines(text: str, table: dict[str, Any]) -> dict[str, int]:
    """The line (from 1) each top-level key is set on: TOML's parser gives no positions."""
    out: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        match = re.match(r"""\s*(?:"([^"]+)"|'([^']+)'|([A-Za-z0-9_-]+))\s*[=.]""", line)
        if match is None and (header := re.match(r"\s*\[+\s*([A-Za-z0-9_-]+)", line)):
            out.setdefault(header.group(1), number)
        elif match is not None:
            out.setdefault(next(g for g in match.groups() if g), number)
    return {k: v for k, v in out.items() if k in table}


# --- a command's options, as click sees them -----------------------------------------------------------


def command_of(group: Any, name: str) -> Any:
    """The click command ``NAME`` of ``group`` (``ionav-viz``'s, as click sees it); InputError naming
    the commands when there is none."""
    commands = getattr(group, "commands", {})
    if name not in commands or name == "run":
        choices = ", ".join(sorted(c for c in commands if c != "run"))
        raise InputError(f"unknown command {name!r}", f"choose one of {choices}", param="config")
    return commands[name]


def _options_of(command: Any) -> dict[str, Any]:
    """``--long-name`` -> the click option, for every option of ``command``."""
    return {opt: p for p in command.params if p.param_type_name == "option" for opt in (*p.opts, *p.secondary_opts)
            if opt.startswith("--")}


def _argument_of(command: Any) -> Any | None:
    return next((p for p in command.params if p.param_type_name == "argument"), None)


def argument_key(param: Any) -> str:
    """The key a command's argument has in an experiment file: ``drives`` (``drive_specs``),
    ``drive``, ``scenario``, ``recordings``..."""
    return param.name.replace("_specs", "s").replace("_spec", "")


def config_words(config: ConfigFile, command: Any) -> tuple[list[str], list[str] | None]:
    """The file's options as command-line words for ``command`` (its own ``command``, if any, must
    be this one), and its arguments (None: none given). InputError naming the file, the line and
    the key for a key that is not an option of the command or a value of the wrong kind."""
    if config.command is not None and config.command != command.name:
        raise InputError(f"{config.where(COMMAND_KEY)}: the file is for '{config.command}', not '{command.name}'",
                         f"run it with 'ionav-viz run {config.path}', or leave out its command line", param="config")
    options = _options_of(command)
    argument = _argument_of(command)
    arguments = config.arguments
    words: list[str] = []
    for key, value in config.options.items():
        if argument is not None and key in (argument.name, argument_key(argument)):
            arguments = _argument_values(config, key, value)
            continue
        option = "--" + key.replace("_", "-")
        param = options.get(option)
        if param is None or option in NOT_CONFIGURATION:
            raise InputError(f"{config.where(key)}: '{command.name}' has no option {option}",
                             _closest(option, options, command.name), param="config")
        words += _option_words(config, key, option, param, value)
    return words, arguments


def _argument_values(config: ConfigFile, key: str, value: Any) -> list[str]:
    items = value if isinstance(value, list) else [value]
    if not all(isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in items):
        raise InputError(f"{config.where(key)}: {value!r} is not a list of names", f'e.g. {key} = ["V-Vw8", "drives/"]',
                         param="config")
    return [str(v) for v in items]


def _option_words(config: ConfigFile, key: str, option: str, param: Any, value: Any) -> list[str]:
    """``option``'s words for ``value``: a flag given or not, a repeatable option once per item, a
    list elsewhere comma-joined."""
    if getattr(param, "is_flag", False) or getattr(param, "count", False):
        if not isinstance(value, bool):
            raise InputError(f"{config.where(key)}: {option} is a flag: give true or false, not {value!r}",
                             f"{key} = true", param="config")
        if option in param.secondary_opts:  # no-idnn = true where the flag reads --idnn/--no-idnn
            value = not value
        if value:
            return [param.opts[0]]
        return [param.secondary_opts[0]] if param.secondary_opts else []
    items = value if isinstance(value, list) else [value]
    if not items or not all(_is_scalar(v) for v in items):
        raise InputError(f"{config.where(key)}: {value!r} is not a value for {option}",
                         f'give text, a number, true/false or a list of them, e.g. {key} = "..."', param="config")
    texts = [_text(v) for v in items]
    if getattr(param, "multiple", False):
        return [w for t in texts for w in (option, t)]
    return [option, ",".join(texts)]


def _is_scalar(value: Any) -> bool:
    return isinstance(value, (str, int, float, bool, date, datetime, time)) and not (isinstance(value, float) and
                                                                                     not math.isfinite(value))


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer():
        return f"{value:g}"
    if isinstance(value, (date, datetime, time)):
        return value.isoformat()
    return str(value)


def _closest(option: str, options: dict[str, Any], command: str) -> str:
    import difflib

    close = difflib.get_close_matches(option, [o for o in options if o not in NOT_CONFIGURATION], n=1)
    return (f"did you mean {close[0].removeprefix('--')}?"
            if close else f"see 'ionav-viz {command} --help' for its options")


# --- the command line, with a file -----------------------------------------------------------------------


def split_words(command: Any, words: list[str]) -> tuple[list[str], list[str]]:
    """A command's words as (options with their values, arguments), by the command's own options
    (``--`` ends the options)."""
    options = _options_of(command)
    short = {opt: p for p in command.params if p.param_type_name == "option" for opt in p.opts
             if not opt.startswith("--")}
    takes_value = {o: not (getattr(p, "is_flag", False) or getattr(p, "count", False))
                   for o, p in {**options, **short}.items()}
    opts, args, i = [], [], 0
    while i < len(words):
        word = words[i]
        if word == "--":
            args += words[i + 1:]
            break
        name = word.split("=", 1)[0]
        if word.startswith("-") and len(word) > 1:
            if takes_value.get(name) and "=" not in word and i + 1 < len(words):
                opts += [word, words[i + 1]]
                i += 2
                continue
            opts.append(word)
        else:
            args.append(word)
        i += 1
    return opts, args


def expand(argv: list[str], group: Any) -> list[str]:
    """``argv`` with experiment files read in: ``run FILE [WORDS]`` becomes ``COMMAND <file's
    options> [WORDS]``, and ``COMMAND ... --config FILE ...`` puts the file's options before the
    command line's (so those win) and its arguments where the command line gives none. Other
    command lines are returned unchanged."""
    at = next((i for i, word in enumerate(argv) if not word.startswith("-")), None)
    if at is None:
        return argv
    head, name, rest = argv[:at], argv[at], argv[at + 1:]
    config = None
    if name == "run":
        if not rest or rest[0].startswith("-"):
            return argv  # 'run --help', or no file: the run command says what it takes
        config, rest = read_config(rest[0]), rest[1:]
        if config.command is None:
            raise InputError(f"{config.path}: no command = \"...\" line: which command does it run?",
                             'add e.g. command = "evaluate"', param="config")
        name = config.command
    if "--" in rest:
        cut = rest.index("--")
        before, after = rest[:cut], rest[cut:]
    else:
        before, after = rest, []
    while CONFIG_OPTION in before or any(w.startswith(CONFIG_OPTION + "=") for w in before):
        i = next(i for i, w in enumerate(before) if w == CONFIG_OPTION or w.startswith(CONFIG_OPTION + "="))
        if before[i] == CONFIG_OPTION:
            if i + 1 >= len(before):
                raise InputError(f"{CONFIG_OPTION} needs a file", f"e.g. {CONFIG_OPTION} experiment.toml",
                                 param="config")
            path, before = before[i + 1], before[:i] + before[i + 2:]
        else:
            path, before = before[i].split("=", 1)[1], before[:i] + before[i + 1:]
        if config is not None:
            raise InputError(f"two experiment files ({config.path} and {path})", "give one", param="config")
        config = read_config(path)
    if config is None:
        return argv
    command = command_of(group, name)
    words, arguments = config_words(config, command)
    opts, args = split_words(command, before + after)
    _CONFIG_IN_USE.append(config)
    return [*head, name, *words, *opts, *(args if args or arguments is None else arguments)]


#: The experiment file the running command line read (for its errors' lines): at most one.
_CONFIG_IN_USE: list[ConfigFile] = []


def forget() -> None:
    """No experiment file in use (a new command line starts)."""
    _CONFIG_IN_USE.clear()


def origin_of(option: str | None) -> str | None:
    """``FILE line N`` where the running command's experiment file set ``option``, else None."""
    if not option or not _CONFIG_IN_USE:
        return None
    config = _CONFIG_IN_USE[-1]
    for key in config.options:
        if "--" + key.replace("_", "-") == option.split()[0]:
            line = config.lines.get(key)
            return f"{config.path}" + (f" line {line}" if line else "")
    return None


# --- the effective configuration -------------------------------------------------------------------------


def effective_config(argv: list[str], group: Any, *, carried: bool = False) -> dict[str, Any] | None:
    """The configuration ``argv`` (a command line, experiment files read in) runs with: ``command``,
    its arguments under the argument's name, and each option given (at a value other than its
    default), by its long name without ``--``; ``carried``: the part a report carries (without
    :data:`HOW_IT_RUNS`). None for a command line that runs no command."""
    at = next((i for i, word in enumerate(argv) if not word.startswith("-")), None)
    if at is None or argv[at] in ("run", "help"):
        return None
    try:
        command = command_of(group, argv[at])
    except InputError:
        return None
    words = [w for w in argv[at + 1:] if w != PRINT_CONFIG_OPTION]
    try:
        ctx = command.make_context(argv[at], words, resilient_parsing=True)
    except Exception:  # a command line click cannot parse even resiliently: no configuration (the command says why)
        return None
    out: dict[str, Any] = {COMMAND_KEY: command.name}
    for param in command.params:
        value = ctx.params.get(param.name)
        source = ctx.get_parameter_source(param.name)
        if source is None or source.name != "COMMANDLINE" or value is None:
            continue
        if param.param_type_name == "argument":
            out[argument_key(param)] = [str(v) for v in (value if isinstance(value, (list, tuple)) else [value])]
            continue
        long = next((o for o in param.opts if o.startswith("--")), param.opts[0])
        if long in NOT_CONFIGURATION or (carried and long in HOW_IT_RUNS):
            continue
        if value == param.default and not getattr(param, "multiple", False):
            continue
        out[long.removeprefix("--")] = _plain(value)
    return out


def _plain(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def to_toml(config: dict[str, Any]) -> str:
    """``config`` as an experiment file: ``command`` first, then its arguments and options."""
    import json

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return json.dumps(str(v), ensure_ascii=False)  # a TOML basic string: JSON's escapes are TOML's

    def key(k: str) -> str:
        return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)

    lines = ["# ionav-viz experiment file: 'ionav-viz run FILE' runs it; 'ionav-viz COMMAND --config FILE' "
             "takes its options"]
    lines += [f"{key(k)} = {value(v)}" for k, v in config.items()]
    return "\n".join(lines) + "\n"


def print_config(argv: list[str], group: Any) -> None:
    """Write the effective configuration of ``argv`` (commands of ``group``) to standard output (``--print-config``)."""
    config = effective_config(argv, group)
    if config is None:
        raise InputError(f"{PRINT_CONFIG_OPTION} needs a command",
                         f"e.g. ionav-viz evaluate V-Vw8 --outage 30s {PRINT_CONFIG_OPTION}", param="config")
    sys.stdout.write(to_toml(config))
