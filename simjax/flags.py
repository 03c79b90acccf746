"""The command-line flags of ``TrainConfig``, one per field, for the commands that take them
(``simjax.train``, ``simjax.fork``).

Their defaults are left to ``TrainConfig``: a parsed namespace holds exactly the flags that
were given (``given_settings``), which is what a fork changes and what ``--resume`` refuses. A new
run's command adds the few that default otherwise there (``with_command_defaults``).
"""

from __future__ import annotations

import argparse
import dataclasses
import math

from simjax import runtime
from simjax.agents import TrainConfig


def parse_bool(text: str) -> bool:
    lowered = text.strip().lower()
    if lowered in ("1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")


def whole_number(text: str) -> int:
    """An integer flag's value, also written as a float that is whole: '4000000', '4e6', '2.5e5'."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value != math.floor(value):
        raise argparse.ArgumentTypeError(f"expected a whole number such as 4000000 or 4e6, got {text!r}")
    return int(value)


whole_number.__name__ = "int"  # what argparse and list_of call the type in their messages

_FIELD_TYPES = {"int": whole_number, "float": float, "str": str, "bool": parse_bool, "float | None": float,
                "bool | None": parse_bool}
_FIELDS = tuple(f.name for f in dataclasses.fields(TrainConfig))


def list_of(kind, choices=None):
    """A flag type for comma-separated values of ``kind``: '1,2,3' -> [1, 2, 3]; each one of
    ``choices`` where given."""
    def parse(text: str) -> list:
        values = [kind(part) for part in text.split(",") if part.strip()]
        bad = [v for v in values if choices is not None and v not in choices]
        if bad:
            raise argparse.ArgumentTypeError(f"invalid choice: {bad[0]!r} (choose from {', '.join(choices)})")
        return values

    parse.__name__ = f"comma-separated {kind.__name__}"
    return parse


def add_config_flags(parser: argparse.ArgumentParser, title: str = "run settings", lists: bool = False) -> None:
    """``--env``, ``--algo``, ... : one flag per TrainConfig field, its default in its help.
    With ``lists`` every flag takes comma-separated values (``simjax.sweep``). A field whose
    metadata has "choices" takes only those."""
    group = parser.add_argument_group(title)
    for field in dataclasses.fields(TrainConfig):
        shown = "" if field.default is None else f" (default: {field.metadata.get('default_shown', field.default)})"
        kind, choices = _FIELD_TYPES[str(field.type)], field.metadata.get("choices")
        typed = {"type": list_of(kind, choices)} if lists else {"type": kind, "choices": choices}
        group.add_argument("--" + field.name.replace("_", "-"), **typed,
                           default=argparse.SUPPRESS, help=field.metadata.get("help", "") + shown)


def given_settings(args: argparse.Namespace) -> dict:
    """The TrainConfig fields given on the command line, by field name."""
    return {name: getattr(args, name) for name in _FIELDS if hasattr(args, name)}


def with_command_defaults(given: dict, lists: bool = False) -> dict:
    """``given`` (``given_settings``) with the settings where a new run from the command line
    defaults otherwise than ``TrainConfig``: ``--precision`` (``runtime.command_default_precision``).
    With ``lists`` each is a one-element list, as ``simjax.sweep``'s flags are."""
    precision = runtime.command_default_precision()
    return {"precision": [precision] if lists else precision, **given}
