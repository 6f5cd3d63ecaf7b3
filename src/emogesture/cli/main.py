"""The ``emogesture`` command: thin subcommands over library functions."""

from __future__ import annotations

import argparse
import sys

from emogesture.version import __version__
from emogesture.cli import (app_commands, data_commands, eval_commands, generate_commands, live_commands,
                            train_commands)
from emogesture.errors import EmogestureError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="emogesture",
        description="Speech to emotional 3D body gestures (SMPL-X), after AMUSE (CVPR 2024).",
    )
    parser.add_argument("--version", action="version", version=f"emogesture {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    data_commands.register(sub)
    train_commands.register(sub)
    eval_commands.register(sub)
    generate_commands.register(sub)
    app_commands.register(sub)
    live_commands.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except EmogestureError as e:
        print(f"emogesture {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"emogesture {args.command}: interrupted; re-run the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
