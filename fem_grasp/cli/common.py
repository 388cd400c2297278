"""What every ``fem-grasp`` command shares: the exit statuses, the bad-input error (exit status 2), printing
unless ``-q``, the progress bar, the cache folder, the scene of a SCENE argument with the options' overrides, and
how numbers are written.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from ..progress import PhaseBar, progress_enabled

__all__ = ["EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_INTERNAL", "EXIT_OK", "BadInput", "Progress", "cache_dir_of", "echo",
           "mm", "number", "progress_on", "scene_of"]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3


class BadInput(Exception):
    """Raised inside a command for input problems: exit status 2."""


# ------------------------------------------------------------------ progress
#: The phase bar of a command (tqdm on a terminal, silent in CI or a pipe: :mod:`fem_grasp.progress`).
Progress = PhaseBar


def progress_on(args: argparse.Namespace) -> bool:
    """Whether the command draws a progress bar (a terminal, not ``-q``, not CI: :mod:`fem_grasp.progress`)."""
    return progress_enabled(quiet=args.quiet)


# ------------------------------------------------------------------ helpers
def echo(args: argparse.Namespace, text: str = "") -> None:
    """Print a line of the command's answer on stdout, unless ``-q``."""
    if not args.quiet:
        print(text)


def cache_dir_of(args: argparse.Namespace) -> Path | None:
    """The cache folder of ``--cache`` (default: the user's cache), or None with ``--no-cache``."""
    from ..io.cache import default_cache_dir

    if args.no_cache:
        return None
    return Path(args.cache) if args.cache else default_cache_dir()


def scene_of(args: argparse.Namespace) -> Any:
    """The :class:`~fem_grasp.io.scene.Scene` of a command's SCENE argument, with ``--quick`` and the overrides its
    options give (``--young``, ``--backend``, ``--no-lift``, ``--allow-implausible-units``, ``--accuracy``)."""
    from ..io.scene import load_scene, resolve_scene, with_overrides

    scene = load_scene(resolve_scene(args.scene), quick=args.quick)
    young = getattr(args, "young", None)
    if young is not None:
        from ..io.scene import check_quantity, parse_quantity

        young = parse_quantity(young, "pressure", "--young")
        check_quantity("--young", young, "Pa")
    scene = with_overrides(scene, backend=getattr(args, "backend", None), young=young,
                           lift=False if getattr(args, "no_lift", False) else None)
    if getattr(args, "allow_implausible_units", False):
        if scene.object.kind != "mesh":
            raise BadInput("--allow-implausible-units: only a mesh file's size and density are checked for their "
                           f"unit; the scene's object is a {scene.object.kind}")
        scene = scene.with_(allow_implausible_units=True)
    from dataclasses import replace

    accuracy = getattr(args, "accuracy", None)
    if accuracy is not None:
        from ..io.scene import parse_accuracy

        scene = replace(scene, accuracy=parse_accuracy(accuracy, "--accuracy"))
    max_contacts = getattr(args, "max_finger_contacts", None)
    if max_contacts is not None:
        if max_contacts < 1:
            raise BadInput(f"--max-finger-contacts must be a whole number ≥ 1, got {max_contacts}")
        scene = replace(scene, max_finger_contacts=max_contacts)
    divisions = getattr(args, "step_divisions", None)
    if divisions is not None:
        if divisions < 1:
            raise BadInput(f"--step-divisions must be a whole number ≥ 1, got {divisions}")
        scene = with_overrides(scene, step_divisions=divisions)
    refinement = getattr(args, "refinement", None)
    if refinement is not None:
        scene = with_overrides(scene, refinement=refinement)
    max_seconds = getattr(args, "max_seconds", None)
    if max_seconds is not None:
        if not (np.isfinite(max_seconds) and max_seconds > 0):
            raise BadInput(f"--max-seconds must be a time in seconds > 0, got {max_seconds:g}")
        scene = with_overrides(scene, max_seconds=max_seconds)
    return scene


def number(x: float | None, unit: str = "", scale: float = 1.0, digits: int = 4) -> str:
    """``x`` × ``scale`` to ``digits`` significant digits, with its unit; "—" for None or a non-finite value."""
    if x is None or not np.isfinite(x):
        return "—"
    return f"{x * scale:.{digits}g}{(' ' + unit) if unit else ''}"


def mm(x: float | None) -> str:
    """A length given in metres, written in millimetres."""
    return number(x, "mm", 1e3)
