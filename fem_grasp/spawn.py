"""Worker processes started by *spawning* need the caller's script to be import-safe.

The placement search's local Dask cluster (:func:`fem_grasp.search` with ``workers`` ≥ 1) and the pictures of the
reports (pyvista, rendered in a freshly spawned process) start new Python processes with the ``spawn`` method.
Each of them imports the script that started the run, as ``__mp_main__``.  A script that calls
``fem_grasp.search(...)`` at its top level, outside ``if __name__ == "__main__":``, would then start the search
again in every new process, which Python refuses ("An attempt has been made to start a new process before the
current process has finished its bootstrapping phase"; Dask reports it as "Nanny failed to start").

:func:`check_main_guard` finds that case before anything starts and raises :class:`MainGuardError` saying what
to write instead::

    import fem_grasp

    if __name__ == "__main__":
        fem_grasp.search("tomato", "out/search", workers=2)

The command line (``fem-grasp``, ``python -m fem_grasp``), an interactive session and a notebook need nothing.
"""

from __future__ import annotations

import ast
import multiprocessing
import sys
from pathlib import Path
from types import FrameType

from .errors import MainGuardError

__all__ = ["MainGuardError", "check_main_guard", "unguarded_main_call"]


def _is_main_test(test: ast.expr) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = [test.left, test.comparators[0]]
    return (any(isinstance(s, ast.Name) and s.id == "__name__" for s in sides)
            and any(isinstance(s, ast.Constant) and s.value == "__main__" for s in sides))


def _guarded_lines(path: Path) -> list[tuple[int, int]]:
    """The line ranges of the ``if __name__ == "__main__":`` blocks of a script (none if it cannot be read)."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (OSError, SyntaxError, UnicodeDecodeError, ValueError):
        return []
    return [(node.lineno, node.end_lineno or node.lineno) for node in ast.walk(tree)
            if isinstance(node, ast.If) and _is_main_test(node.test)]


def unguarded_main_call(frame: FrameType | None = None) -> str | None:
    """Where (``"script.py, line N"``) the running script calls into fem_grasp at its top level outside
    ``if __name__ == "__main__":``, so that a spawned process would run the call again; None when it is safe.

    Safe: an interactive session or notebook (no script file), ``python -m package`` (spawned processes do not
    run a package's ``__main__``), and a call from inside the guard.  In a spawned process that is still
    importing the script (the call about to be repeated) the answer is the script too.
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or path is None:
        return None
    spec = getattr(main, "__spec__", None)
    name = getattr(spec, "name", None)
    if name is not None and (name == "__main__" or name.endswith(".__main__")):
        return None
    if getattr(multiprocessing.current_process(), "_inheriting", False) or main.__name__ == "__mp_main__":
        return f"{path} (while a spawned process imports it)"
    frame = frame if frame is not None else sys._getframe(1)
    top = None
    while frame is not None:  # the outermost frame running the script's own top-level code
        if frame.f_globals is vars(main) and frame.f_code.co_name == "<module>":
            top = frame
        frame = frame.f_back
    if top is None:
        return None
    line = top.f_lineno
    if any(lo <= line <= hi for lo, hi in _guarded_lines(Path(path))):
        return None
    return f"{path}, line {line}"


def check_main_guard(what: str, otherwise: str = "") -> None:
    """Raise :class:`~fem_grasp.errors.MainGuardError` when ``what`` (e.g. ``"fem_grasp.search(..., workers=2)"``),
    which starts spawned processes, is called from a script's top level outside ``if __name__ == "__main__":``
    (module notes); ``otherwise`` names a way to run it without new processes, for the message."""
    where = unguarded_main_call(sys._getframe(1))
    if where is None:
        return
    raise MainGuardError(
        f"{what} starts worker processes with the 'spawn' method, and each of them imports the script that "
        f"called it ({where}), which would start the same work again in every one of them (Dask: \"Nanny failed "
        "to start\"). Put the call under the main guard:\n\n"
        "    if __name__ == \"__main__\":\n"
        "        ...  # the call\n\n"
        + (f"({otherwise})" if otherwise else ""))
