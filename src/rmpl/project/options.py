"""A trial's ``rmpl run`` options: ``rmpl.toml`` files, Pose2Sim's ``Config.toml``, command line.

The valid keys are ``rmpl run``'s own options, read from its argparse parser
(:func:`rmpl.cli.run.register`), so the two never drift: a key is an option's name without
its dashes, with ``-`` or ``_`` (``max-gap = 10``, ``max_gap = 10``, ``no-pictures = true``).
Every value is checked by that parser at once, before any trial runs: an unknown key or a bad
value is one line naming the file and the key. ``out`` is refused (``rmpl batch`` gives each
trial its folder). A path (``calib``, ``keypoints``, ``videos``, ``images``, ``model``,
``floor``) is relative to the folder of the ``rmpl.toml`` that names it.

Priority, lowest first: what the layout finds (calibration, inputs) and what a Pose2Sim
``Config.toml`` says (:func:`pose2sim_settings`), the project's ``rmpl.toml``, a
participant's, the trial's, then the command line. ``keypoints``, ``videos`` and ``images``
are one setting (the input): a higher level naming any of them replaces the lower's.
"""

from __future__ import annotations

import argparse
import functools
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from rmpl.errors import InputError

__all__ = [
    "CONFIG_NAME",
    "Options",
    "Pose2SimSettings",
    "merge",
    "parse_command_line",
    "pose2sim_settings",
    "read_config",
    "run_argv",
]

#: The name of rmpl's configuration file at the project, participant and trial levels.
CONFIG_NAME = "rmpl.toml"
#: Pose2Sim's configuration file (read for frame rate, participants and excluded trials).
POSE2SIM_CONFIG = "Config.toml"

#: ``rmpl run`` options that ``rmpl batch`` sets itself.
_BATCH_SETS = {"out": "rmpl batch gives each trial its own folder under --out"}
#: The options naming the input: one setting, the highest level's wins.
SOURCES = ("keypoints", "videos", "images")
#: Options whose values may be paths, relative to the configuration file naming them.
_PATHS = {"calib", "keypoints", "videos", "images", "model", "floor"}

#: Options as parsed raw tokens: dest -> the tokens after the option (``[]`` for a flag set,
#: None for a flag unset).
Options = dict[str, list[str] | None]


class _Refusing(argparse.ArgumentParser):
    """A parser whose errors are :class:`InputError` (no usage text, no exit)."""

    def error(self, message: str):  # noqa: D102 (argparse's hook)
        raise InputError(None, None, "valid rmpl run options", message)


@functools.cache
def _run_parser() -> _Refusing:
    """``rmpl run``'s parser with nothing required and no defaults: parsing gives only the
    options given."""
    from rmpl.cli.run import register

    parser = _Refusing(
        prog="rmpl run", add_help=False, allow_abbrev=False, argument_default=argparse.SUPPRESS
    )
    register(parser)
    for action in parser._actions:
        action.required = False
        action.default = argparse.SUPPRESS
    for group in parser._mutually_exclusive_groups:
        group.required = False
    return parser


def run_actions() -> dict[str, argparse.Action]:
    """``rmpl run``'s options by dest (``max_gap``), from its own parser."""
    return {a.dest: a for a in _run_parser()._actions if a.option_strings and a.dest != "help"}


def _flag(action: argparse.Action) -> bool:
    return action.nargs == 0


def _tokens(dest: str, raw: Options) -> list[str]:
    action = run_actions()[dest]
    value = raw[dest]
    if value is None:
        return []
    return [action.option_strings[-1], *value]


def _check(raw: Options, where: Path | str | None) -> None:
    """Parse the tokens with ``rmpl run``'s parser: a bad value is an InputError."""
    argv = [t for dest in raw for t in _tokens(dest, raw)]
    try:
        _run_parser().parse_args(argv)
    except InputError as e:
        raise InputError(where, None, "valid rmpl run options", e.got) from None


def _key(name: str, path: Path) -> str:
    dest = name.replace("-", "_")
    if dest in _BATCH_SETS:
        raise InputError(path, name, f"no {name!r} ({_BATCH_SETS[dest]})", name)
    if dest not in run_actions():
        keys = ", ".join(k.replace("_", "-") for k in run_actions() if k not in _BATCH_SETS)
        raise InputError(path, name, f"one of rmpl run's options: {keys}", "an unknown key")
    return dest


def _value_tokens(dest: str, value, path: Path) -> list[str] | None:
    action = run_actions()[dest]
    name = dest.replace("_", "-")
    if _flag(action):
        if not isinstance(value, bool):
            raise InputError(path, name, "true or false", repr(value))
        return [] if value else None
    values = value if isinstance(value, list) else [value]
    if action.nargs != "+" and len(values) != 1:
        raise InputError(path, name, "one value", repr(value))
    if not values or any(isinstance(v, bool | dict | list) for v in values):
        raise InputError(path, name, "a string or a number (a list of them for "
                         f"{'/'.join(SOURCES)})", repr(value))  # fmt: skip
    tokens = [str(v) for v in values]
    if dest in _PATHS:
        tokens = [_relative_to(t, path.parent, dest) for t in tokens]
    return tokens


def _relative_to(token: str, base: Path, dest: str) -> str:
    """A path of a configuration file, relative to its folder (a floor such as ``z=0`` or a
    shipped model name stays as it is)."""
    p = Path(token).expanduser()
    if p.is_absolute():
        return str(p)
    if dest in ("model", "floor") and not (base / p).exists():
        return token
    return str(base / p)


def read_config(path: Path) -> Options:
    """An ``rmpl.toml``'s options as raw tokens, each checked by ``rmpl run``'s parser.

    Raises:
        InputError: an unreadable file, an unknown key, ``out``, or a bad value.
    """
    try:
        doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise InputError(path, None, "a readable TOML file of rmpl run options", e) from None
    raw: Options = {}
    for name, value in doc.items():
        if isinstance(value, dict):
            raise InputError(path, name, "rmpl run options as top-level keys (no tables)",
                             "a table")  # fmt: skip
        dest = _key(name, path)
        raw[dest] = _value_tokens(dest, value, path)
    _check(raw, path)
    return raw


def parse_command_line(argv: list[str]) -> Options:
    """``rmpl run`` options given to ``rmpl batch`` on the command line, as raw tokens
    (kept as typed: ``--duplicate-tolerance off`` stays "off").

    Raises:
        InputError: an unknown option, ``--out`` (``rmpl batch``'s own), or a bad value.
    """
    by_option = {o: d for d, a in run_actions().items() for o in a.option_strings}
    raw: Options = {}
    i = 0
    while i < len(argv):
        option, _, inline = argv[i].partition("=")
        dest = by_option.get(option)
        if dest is None or dest in _BATCH_SETS:
            expected = "an rmpl run option" if dest is None else _BATCH_SETS[dest]
            raise InputError(None, option, expected, argv[i])
        j = i + 1
        while not inline and j < len(argv) and not argv[j].startswith("--"):
            j += 1
        raw[dest] = [inline] if inline else argv[i + 1 : j]
        i = j
    _check(raw, "the command line")
    return raw


_PREFIX = "run_option_"


def add_run_options(group) -> None:
    """``rmpl run``'s options (but ``--out``) on another command's parser (``rmpl batch``),
    from ``rmpl run``'s own parser; :func:`given_run_options` reads them back."""
    for dest, a in run_actions().items():
        if dest in _BATCH_SETS:
            continue
        kwargs = {"dest": _PREFIX + dest, "default": argparse.SUPPRESS, "help": a.help}
        if _flag(a):
            kwargs["action"] = "store_true"
        else:
            kwargs.update(nargs=a.nargs, choices=a.choices, metavar=a.metavar)
        group.add_argument(*a.option_strings, **kwargs)


def given_run_options(args: argparse.Namespace) -> Options:
    """The ``rmpl run`` options given to the command (:func:`add_run_options`), as raw
    tokens, checked by ``rmpl run``'s parser."""
    raw: Options = {}
    for key, value in vars(args).items():
        if key.startswith(_PREFIX):
            dest = key[len(_PREFIX) :]
            raw[dest] = (
                []
                if value is True
                else [str(v) for v in (value if isinstance(value, list) else [value])]
            )
    _check(raw, "the command line")
    return raw


def merge(*levels: Options) -> Options:
    """Options of several levels, lowest first; the input (keypoints / videos / images) is
    one setting."""
    out: Options = {}
    for level in levels:
        if any(s in level for s in SOURCES):
            for s in SOURCES:
                out.pop(s, None)
        out.update(level)
    return out


def run_argv(options: Options, out: Path) -> list[str]:
    """The ``rmpl run`` command line of merged options, writing to ``out``."""
    argv = [t for dest in options for t in _tokens(dest, options)]
    return ["run", *argv, "--out", str(out)]


@dataclass
class Pose2SimSettings:
    """What rmpl reads from a trial's Pose2Sim ``Config.toml`` files (session, participant,
    trial; the lower overriding the upper, key by key).

    Attributes:
        fps: ``[project] frame_rate`` when a number ('auto': the input's own).
        heights: ``participant_height`` in metres (the participants' given heights; rmpl
            estimates its own, the summary shows both), or None ('auto').
        masses: ``participant_mass`` in kg (rmpl does not use it; for OpenSim).
        excluded: ``exclude_from_batch``: trials to skip, relative to the session.
        notes: what was read and what is not applied, one sentence each.
    """

    fps: float | None = None
    heights: list[float] | None = None
    masses: list[float] | None = None
    excluded: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _deep_merge(low: dict, high: dict) -> dict:
    out = dict(low)
    for k, v in high.items():
        out[k] = (
            _deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
        )
    return out


def _numbers(value, path: Path, key: str) -> list[float] | None:
    if isinstance(value, str):
        return None  # 'auto'
    values = value if isinstance(value, list) else [value]
    if not values or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in values
    ):
        raise InputError(path, f"project.{key}", "a number, a list of numbers or 'auto'", value)
    return [float(v) for v in values]


def pose2sim_settings(paths: list[Path]) -> Pose2SimSettings:
    """Read Pose2Sim ``Config.toml`` files, the session's first, the trial's last.

    Raises:
        InputError: an unreadable file, or a value of the wrong kind.
    """
    doc: dict = {}
    for path in paths:
        try:
            level = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise InputError(path, None, "a readable Pose2Sim Config.toml", e) from None
        doc = _deep_merge(doc, level)
    project = doc.get("project", {}) if isinstance(doc.get("project", {}), dict) else {}
    where = paths[-1] if paths else Path(POSE2SIM_CONFIG)
    s = Pose2SimSettings()
    rate = project.get("frame_rate", "auto")
    if not (rate == "auto" or isinstance(rate, int | float) and not isinstance(rate, bool)):
        raise InputError(where, "project.frame_rate", "a frame rate > 0 or 'auto'", rate)
    if rate != "auto":
        if not rate > 0:
            raise InputError(where, "project.frame_rate", "a frame rate > 0 or 'auto'", rate)
        s.fps = float(rate)
        s.notes.append(f"frame rate {rate:g} from Config.toml [project] frame_rate")
    s.heights = _numbers(project.get("participant_height", "auto"), where, "participant_height")
    s.masses = _numbers(project.get("participant_mass", "auto"), where, "participant_mass")
    if s.heights:
        s.notes.append(f"participant height {_list(s.heights)} m from Config.toml (shown beside "
                       "rmpl's estimate; rmpl does not scale to it)")  # fmt: skip
    if s.masses:
        s.notes.append(f"participant mass {_list(s.masses)} kg from Config.toml (not used by "
                       "rmpl; for OpenSim scaling)")  # fmt: skip
    excluded = project.get("exclude_from_batch", [])
    if not isinstance(excluded, list) or not all(isinstance(e, str) for e in excluded):
        raise InputError(where, "project.exclude_from_batch", "a list of trial folders", excluded)
    s.excluded = [e.replace("\\", "/").strip("/") for e in excluded]
    frame_range = project.get("frame_range", "all")
    if frame_range not in ("all", "auto", None, []):
        s.notes.append(f"Config.toml frame_range {frame_range} is not applied: rmpl run reads "
                       "every frame")  # fmt: skip
    if project.get("multi_person") is False:
        s.notes.append("Config.toml multi_person = false is not applied: rmpl tracks everyone")
    return s


def _list(values: list[float]) -> str:
    return ", ".join(f"{v:g}" for v in values)
