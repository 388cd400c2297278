"""The ``fem-grasp`` command line (also ``python -m fem_grasp``).

Subcommands::

    fem-grasp run SCENE [--quick] [--out DIR] [--report] [--young E] [--no-lift] [--accuracy A]   squeeze and lift (Algorithm 1)
    fem-grasp rest SCENE [--quick] [--out DIR]              the resting state only (§III-A)
    fem-grasp mesh INPUT -o OUTPUT [--vertices N | --size H] [--units mm]   closed surface scan → tetrahedra
    fem-grasp info PATH                                     a mesh, a surface, a scene, a result.json or a .pvd
    fem-grasp report DIR [--colour von_mises]               report.html + pictures from a run's output
    fem-grasp search SCENE --out DIR [--workers N | --scheduler tcp://HOST:PORT]
                                                            where to grasp: Algorithm 1 for many placements
    fem-grasp scenes                                        the scenes shipped with fem_grasp

Every command takes -v/-vv (the library's log on stderr), --log-file FILE and -q; a progress bar is
drawn on a terminal only (:mod:`fem_grasp.progress`).  SCENE is a TOML file (:mod:`fem_grasp.io.scene`)
or the name of a shipped scene (``tomato``, ``orange``, ``steam_bun``, ``football``, ``foam_block``,
``slippery_ball``); ``run`` takes the same path as :func:`fem_grasp.run_scene`.  Exit status: 0 success, 1 the grasp failed (a valid
answer: the object cannot be picked up so), 2 bad input (the message names
it) or a missing optional dependency (the message names the extra that installs it, e.g.
``pip install "fem_grasp[report]"``), 3 an internal error (a bug: please report it).  ``fem-grasp --version``
prints the version.

:func:`main` takes ``argv`` and returns the exit status, so tests call it
in-process.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from typing import Any, Iterator, Sequence

from .common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_INTERNAL, EXIT_OK, BadInput
from .parser import build_parser

__all__ = ["main", "EXIT_OK", "EXIT_FAILED", "EXIT_BAD_INPUT", "EXIT_INTERNAL"]

log = logging.getLogger(__name__)


@contextlib.contextmanager
def _logging(args: argparse.Namespace) -> Iterator[None]:
    """Route fem_grasp's log records to stderr at the chosen level for one command (and, with ``--log-file``,
    every record from INFO up — DEBUG with -vv — to that file); show fem_grasp's warnings (units, locking) as
    one line each; restore everything afterwards.

    ``main`` runs in-process (tests, notebooks), so the level and handler it sets must not outlive it.
    """
    import warnings

    level = logging.ERROR if args.quiet else [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    root = logging.getLogger("fem_grasp")
    old_level, old_propagate = root.level, root.propagate
    handlers: list[logging.Handler] = []
    console = logging.StreamHandler(sys.stderr)
    console.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    console.setLevel(level)
    handlers.append(console)
    file_level = level
    if getattr(args, "log_file", None):
        try:
            fh = logging.FileHandler(args.log_file, encoding="utf-8")
        except OSError as exc:
            print(f"fem-grasp: error: --log-file {args.log_file}: {exc}", file=sys.stderr)
            raise SystemExit(EXIT_BAD_INPUT) from None
        file_level = logging.DEBUG if args.verbose >= 2 else logging.INFO
        fh.setLevel(file_level)
        fh.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s: %(message)s"))
        handlers.append(fh)
    root.setLevel(min(level, file_level))
    for h in handlers:
        root.addHandler(h)
    root.propagate = False
    # The accuracy loop's levels are shown as they finish, even at the default level: a refinement can take
    # minutes, and silence then reads as a hang.
    levels = logging.getLogger("fem_grasp.grasp.accuracy")
    old_levels_level = levels.level
    progress = None
    if not args.quiet and level > logging.INFO:
        progress = logging.StreamHandler(sys.stderr)
        progress.setFormatter(logging.Formatter("%(message)s"))
        progress.addFilter(lambda record: record.levelno == logging.INFO and record.msg.startswith("accuracy level"))
        levels.setLevel(logging.INFO)
        levels.addHandler(progress)
    old_show = warnings.showwarning

    def show(message: Any, category: type, filename: str, lineno: int, file: Any = None, line: Any = None) -> None:
        if issubclass(category, UserWarning) and "fem_grasp" in str(filename):
            logging.getLogger("fem_grasp.warnings").warning("%s", message)
        else:
            old_show(message, category, filename, lineno, file, line)

    try:
        with warnings.catch_warnings():  # the caller's filters stay (pytest's errors, -W); only the display changes
            warnings.showwarning = show
            yield
    finally:
        warnings.showwarning = old_show
        for h in handlers:
            root.removeHandler(h)
            h.close()
        if progress is not None:
            levels.removeHandler(progress)
            progress.close()
        levels.setLevel(old_levels_level)
        root.setLevel(old_level)
        root.propagate = old_propagate


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0 success, 1 grasp failed, 2 bad input, 3 internal error)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2)
        return int(exc.code or 0)
    args.argv = argv
    try:
        with _logging(args):
            return _dispatch(args)
    except SystemExit as exc:  # --log-file cannot be opened
        return int(exc.code or 0)


def _dispatch(args: argparse.Namespace) -> int:
    from ..errors import (
        FrictionError,
        MeshError,
        MissingExtraError,
        OutputError,
        RestConvergenceError,
        SceneError,
        SurfaceError,
    )

    try:
        return int(args.func(args))
    except MissingExtraError as exc:  # an optional dependency: the message names the extra that brings it
        print(f"fem-grasp {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (BadInput, SceneError, SurfaceError, MeshError, OutputError, FileNotFoundError) as exc:
        print(f"fem-grasp {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except ValueError as exc:  # pickup()/rest() refuse bad scene values with ValueError subclasses
        print(f"fem-grasp {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (FrictionError, RestConvergenceError) as exc:
        # No resting state: the object slides off or never settles on the table.  An answer, not a bug.
        print(f"fem-grasp {args.command}: the object does not come to rest on the table: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("fem-grasp: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - report, do not dump a traceback on the user
        log.debug("internal error", exc_info=True)
        print(f"fem-grasp {args.command}: internal error ({type(exc).__name__}): {exc} — rerun with -vv for the "
              "traceback and report it", file=sys.stderr)
        return EXIT_INTERNAL
