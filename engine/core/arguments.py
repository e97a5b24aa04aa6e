"""Command-line pieces shared by engine/cli.py and the study modules (which cannot import the cli): numbers
refused outside their range, deprecated flag aliases, one-line errors. argparse only; no bpy."""
from __future__ import annotations

import argparse
import sys

from .options import Option, range_text

# Blender's own limits for scene.render.resolution_x/y (it silently clamps anything below 4).
RESOLUTION_RANGE = (4, 65536)
# Cycles' limits for scene.cycles.samples.
CYCLES_SAMPLES_RANGE = (1, 1 << 24)


def ranged(kind=int, lo=None, hi=None):
    """An argparse `type` that parses `kind` and refuses values outside lo … hi, naming the range."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {'an integer' if kind is int else 'a number'}, got '{text}'") from None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"{text} is out of range ({range_text(lo, hi)})")
        return value
    parse.__name__ = kind.__name__          # argparse names the type in its messages
    return parse


def option_type(opt: Option):
    """The argparse `type` of a numeric Option: its own kind and range."""
    return ranged(type(opt.default), opt.min, opt.max)


class DeprecatedAlias(argparse.Action):
    """A hidden old spelling of a flag: stores into the new flag's destination and says so on stderr."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs):
        kwargs.setdefault("help", argparse.SUPPRESS)
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"penumbra: {option_string} is deprecated; use {self.new}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_alias(parser, old: str, action: argparse.Action) -> None:
    """Register `old` as a hidden, deprecated spelling of the flag `action` (what add_argument returned)."""
    parser.add_argument(old, action=DeprecatedAlias, new=action.option_strings[0], dest=action.dest,
                        type=action.type, nargs=action.nargs, metavar=action.metavar, default=argparse.SUPPRESS)


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: the command, the problem, exit status 2 (argparse's own)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message} (see --help)\n")
