"""Commands that forward to other commands: ``python -m verification STUDY …`` and ``… friction ACTION …``."""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Callable


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Each command and its line of help on one line."""

    def __init__(self, prog: str) -> None:
        super().__init__(prog, max_help_position=30)
        self._action_max_length = 18  # room for the longest name (random_scenes) beside its help


def dispatch(prog: str, description: str, commands: dict[str, tuple[str, str]], argv: list[str] | None,
             metavar: str = "COMMAND", epilog: str | None = None) -> int:
    """Forward ``argv[1:]`` to the ``main`` of the command named by ``argv[0]``.

    ``commands`` maps each name to (one line of help, the module whose ``main(argv)`` runs it); a module is
    imported only when its command runs, so that ``--help`` stays quick.  Anything else — no command, an
    unknown one, ``--help`` — goes to an argparse parser listing the commands (exit 0 for help, 2 otherwise).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] in commands:
        main: Callable[[list[str]], int] = importlib.import_module(commands[args[0]][1]).main
        return int(main(args[1:]) or 0)
    ap = argparse.ArgumentParser(prog=prog, description=description, epilog=epilog,
                                 formatter_class=_Formatter)
    sub = ap.add_subparsers(dest="command", metavar=metavar, required=True)
    for name, (line, _) in commands.items():
        sub.add_parser(name, help=line, add_help=False)
    ap.parse_args(args[:1])  # --help, no command or an unknown one: argparse prints and exits
    return 2
