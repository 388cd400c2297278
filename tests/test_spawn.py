"""A script that starts spawned processes (a search's Dask workers, the reports' pictures) outside
``if __name__ == "__main__":`` is told so before anything starts, instead of failing inside Dask."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(tmp_path: Path, code: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    script = tmp_path / "script.py"
    script.write_text(textwrap.dedent(code))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=timeout,
                          cwd=tmp_path, env=env)


def test_an_unguarded_search_with_workers_is_refused_naming_the_guard(tmp_path):
    done = _run(tmp_path, """
        import fem_grasp

        fem_grasp.search("foam_block", None, quick=True, candidates=2, workers=2)
        """)
    assert done.returncode != 0
    assert "MainGuardError" in done.stderr and 'if __name__ == "__main__":' in done.stderr, done.stderr
    assert "script.py, line 4" in done.stderr and "workers=0" in done.stderr, done.stderr
    assert "RuntimeError: Nanny failed" not in done.stderr and "bootstrapping phase" not in done.stderr


def test_the_guard_is_recognised_and_so_are_calls_from_functions(tmp_path):
    done = _run(tmp_path, """
        from fem_grasp.spawn import unguarded_main_call

        def nested():
            return unguarded_main_call()

        print("top", nested())
        if __name__ == "__main__":
            print("guarded", nested())
        """)
    assert done.returncode == 0, done.stderr
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    assert lines["top"].endswith("script.py, line 7"), lines
    assert lines["guarded"] == "None", lines


def test_an_interactive_caller_needs_no_guard():
    from fem_grasp.spawn import unguarded_main_call

    assert unguarded_main_call() is None  # pytest's __main__ is not a script calling fem_grasp at its top level
