"""Progress bars for long runs: tqdm on a terminal, nothing in CI, in a pipe or when asked to be quiet.

``fem-grasp``, the verification (``python -m verification STUDY``: convergence, cross-checks) and other
long loops share these, so that all behave alike:

* :func:`progress_enabled` — a bar is drawn only when stderr is a terminal, ``$CI`` is unset (GitHub
  Actions, GitLab and most CI services set it) and ``$FEM_GRASP_PROGRESS`` is not ``0`` (``1`` forces
  bars on); tqdm missing means no bar;
* :func:`progress` — wraps an iterable in a bar (or returns it unchanged);
* :class:`PhaseBar` — one step per named phase (mesh, rest, pickup, …) with the elapsed time, for work
  that reports no progress from inside.

Bars go to stderr and never into logs or output files.
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Any, Iterable, Iterator, Sequence, TypeVar

__all__ = ["PhaseBar", "progress", "progress_enabled"]

T = TypeVar("T")


def progress_enabled(quiet: bool = False, stream: Any = None) -> bool:
    """Whether to draw bars: not ``quiet``, stderr (or ``stream``) a terminal, not in CI (module notes)."""
    if quiet:
        return False
    forced = os.environ.get("FEM_GRASP_PROGRESS", "").strip()
    if forced == "0":
        return False
    if forced == "1":
        return _tqdm() is not None
    if os.environ.get("CI", "").strip().lower() not in ("", "0", "false"):
        return False
    stream = sys.stderr if stream is None else stream
    try:
        tty = bool(stream.isatty())
    except (AttributeError, ValueError):
        tty = False
    return tty and _tqdm() is not None


def _tqdm() -> Any:
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm


def progress(iterable: Iterable[T], total: int | None = None, desc: str = "", enabled: bool | None = None,
             unit: str = "it") -> Iterable[T]:
    """``iterable`` with a tqdm bar on stderr when :func:`progress_enabled` (or ``enabled``) says so."""
    on = progress_enabled() if enabled is None else enabled
    tqdm = _tqdm() if on else None
    if tqdm is None:
        return iterable
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True)


class PhaseBar:
    """A phase-by-phase bar (tqdm) showing the current phase and the elapsed time; silent when disabled."""

    def __init__(self, phases: Sequence[str], enabled: bool | None = None) -> None:
        self.bar = None
        on = progress_enabled() if enabled is None else enabled
        tqdm = _tqdm() if on else None
        if tqdm is not None:
            self.bar = tqdm(total=len(phases), unit="phase", file=sys.stderr, leave=False, mininterval=0,
                            bar_format="{desc:<28} {bar:20} {n_fmt}/{total_fmt} [{elapsed}]")

    @contextlib.contextmanager
    def phase(self, name: str) -> Iterator[None]:
        """Show ``name`` while the block runs; advance by one when it ends."""
        if self.bar is not None:
            self.bar.set_description_str(name, refresh=True)
        yield
        if self.bar is not None:
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
