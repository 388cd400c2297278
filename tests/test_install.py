"""What a plain ``pip install fem_grasp`` gives: the shipped scenes with their meshes as package data, the version,
and, for each optional extra that is not installed, exit status 2 and a message that names the extra.

A missing module is simulated in-process (``sys.modules[name] = None`` makes ``import name`` fail), so these run
wherever the extras are installed too.  ``make test-pip`` runs the whole suite against an installed wheel.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.resources
import importlib.util
import logging
import sys
import time
from pathlib import Path

import pytest

import fem_grasp
from fem_grasp import errors
from fem_grasp.cli import main
from fem_grasp.grasp import objects
from fem_grasp.io.scene import load_scene, resolve_scene, shipped_scenes
from tests.helpers import ROOT, box_scene_toml, icosphere, write_stl


def _missing(monkeypatch: pytest.MonkeyPatch, *modules: str) -> None:
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)  # `import name` now raises ModuleNotFoundError


def _names_the_extra(err: str, extra: str) -> bool:
    return f'pip install "fem_grasp[{extra}]"' in err and "internal error" not in err


def _first_missing(*checked: str) -> str:
    """The first of the modules a command checks, in its order, that cannot be found (simulated or not)."""
    return next(m for m in checked if importlib.util.find_spec(m) is None)


# ----------------------------------------------------------------- shipped scenes and their meshes
PAPER_SCENES = sorted(n for n, p in shipped_scenes().items() if load_scene(p).object.kind == "paper")


def test_the_six_scenes_ship_and_the_paper_ones_name_their_object():
    assert set(shipped_scenes()) == {"tomato", "orange", "steam_bun", "football", "foam_block", "slippery_ball"}
    assert set(PAPER_SCENES) >= {"tomato", "orange", "steam_bun", "football"}


@pytest.mark.parametrize("name", objects.NAMES)
def test_paper_meshes_are_package_data(name):
    """The committed meshes are resources of the package (what a wheel installs), where objects looks for them."""
    resource = importlib.resources.files("fem_grasp") / "scenes" / "meshes" / f"{name}.vtu"
    assert resource.is_file()
    with importlib.resources.as_file(resource) as path:
        assert Path(path).resolve() == objects.mesh_path(name).resolve()
    mesh = objects.load_mesh(name)
    assert abs(mesh.n_points - objects.TABLE_I[name].vertices) <= 0.05 * objects.TABLE_I[name].vertices


@pytest.mark.parametrize("name", sorted(shipped_scenes()))
def test_every_shipped_scene_loads_with_its_full_mesh(name):
    """Every shipped scene is read and its object built from the installed files alone, without gmsh: the paper
    scenes load their committed meshes, the box is a structured grid."""
    scene = load_scene(resolve_scene(name))
    assert scene.object.kind in ("paper", "box") and scene.object.vertices is None
    body = scene.body(cache_dir=None)
    assert body.mesh.n_points > 100 and body.weight > 0


def test_package_data_declares_every_shipped_file():
    """pyproject's package-data covers every file under fem_grasp/scenes (a new mesh cannot be left out of the
    wheel); in the source tree only."""
    pyproject = ROOT / "pyproject.toml"
    package = Path(fem_grasp.__file__).resolve().parent
    if not pyproject.exists() or not (ROOT / "fem_grasp").resolve() == package:
        pytest.skip("pyproject.toml belongs to the source tree")
    import fnmatch

    tomllib = pytest.importorskip("tomllib")
    patterns = tomllib.loads(pyproject.read_text())["tool"]["setuptools"]["package-data"]["fem_grasp"]
    shipped = [p.relative_to(package).as_posix() for p in (package / "scenes").rglob("*")
               if p.is_file() and "__pycache__" not in p.parts]
    assert any(s.endswith(".vtu") for s in shipped)
    left_out = [s for s in shipped if not any(fnmatch.fnmatch(s, pat) for pat in patterns)]
    assert not left_out, f"not declared in [tool.setuptools.package-data]: {left_out}"


def test_a_users_scene_resolves_its_mesh_beside_its_own_file(tmp_path, monkeypatch):
    """A scene file of the user's names its mesh relative to itself, from whatever folder it is run."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "mine.vtu").write_bytes(objects.mesh_path("tomato").read_bytes())
    (folder / "mine.toml").write_text(box_scene_toml().replace('box = ["3 cm", "4 cm", "3 cm"]\ndivisions = [2, 2, 2]',
                                                               'mesh = "mine.vtu"'))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    scene = load_scene(Path("..") / "scenes" / "mine.toml")
    assert scene.object.mesh.resolve() == (folder / "mine.vtu").resolve()
    assert scene.load_mesh().n_points == objects.load_mesh("tomato").n_points


def test_a_folder_named_like_a_shipped_scene_does_not_hide_it(tmp_path, monkeypatch):
    """`fem-grasp run tomato --out tomato`, run twice: the output folder is not taken for the scene."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tomato").mkdir()
    assert resolve_scene("tomato") == shipped_scenes()["tomato"]


# ----------------------------------------------------------------- the version
def test_version_option_prints_the_package_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.split() == ["fem-grasp", fem_grasp.__version__]


def test_version_is_the_source_trees_or_the_installed_distributions():
    """A source checkout reports its pyproject's version; an installed wheel its metadata's."""
    pyproject = ROOT / "pyproject.toml"
    if pyproject.exists() and (ROOT / "fem_grasp").resolve() == Path(fem_grasp.__file__).resolve().parent:
        tomllib = pytest.importorskip("tomllib")
        assert fem_grasp.__version__ == tomllib.loads(pyproject.read_text())["project"]["version"]
    else:
        assert fem_grasp.__version__ == importlib.metadata.version("fem_grasp")
    assert fem_grasp.__version__[0].isdigit()


# ----------------------------------------------------------------- missing extras: exit 2, the extra named
def test_require_raises_an_import_error_naming_the_extra(monkeypatch):
    _missing(monkeypatch, "pyvista")
    with pytest.raises(errors.MissingExtraError) as info:
        errors.require("pyvista", "report", "Drawing")
    assert isinstance(info.value, ImportError) and info.value.extra == "report" and info.value.name == "pyvista"
    assert str(info.value).startswith("Drawing needs the 'report' extra (pyvista is not installed)")
    with pytest.raises(ValueError, match="unknown extra"):
        errors.require("numpy", "no-such-extra", "x")
    assert errors.require("numpy", "fast", "x").__name__ == "numpy"


@pytest.mark.parametrize("module", ["pyvista", "matplotlib"])
def test_run_report_without_the_report_extra_exits_2_before_the_pickup(module, monkeypatch, capsys, tmp_path):
    _missing(monkeypatch, module)
    t0 = time.perf_counter()
    code = main(["run", "foam_block", "--out", str(tmp_path / "o"), "--report", "--no-cache"])
    err = capsys.readouterr().err
    assert code == 2 and _names_the_extra(err, "report")
    assert f"{_first_missing('matplotlib', 'pyvista')} is not installed" in err
    assert time.perf_counter() - t0 < 20 and not (tmp_path / "o" / "result.json").exists()  # said before the run


def test_report_command_without_the_report_extra_exits_2(monkeypatch, capsys, tmp_path):
    out = tmp_path / "o"
    assert main(["run", "foam_block", "--quick", "--no-lift", "--no-cache", "--quiet", "--out", str(out)]) in (0, 1)
    _missing(monkeypatch, "pyvista")
    assert main(["report", str(tmp_path / "no-such-run")]) == 2  # a wrong folder is said first
    assert "result.json" in capsys.readouterr().err
    assert main(["report", str(out)]) == 2
    assert _names_the_extra(capsys.readouterr().err, "report") and not (out / "report.html").exists()


@pytest.mark.parametrize("module,workers", [("pandas", "0"), ("pyarrow", "0"), ("distributed", "2")])
def test_search_without_the_search_extra_exits_2(module, workers, monkeypatch, capsys, tmp_path):
    _missing(monkeypatch, module)
    code = main(["search", "foam_block", "--workers", workers, "--out", str(tmp_path / "s"), "--no-cache"])
    err = capsys.readouterr().err
    checked = ("pandas", "distributed", "pyarrow") if workers != "0" else ("pandas", "pyarrow")
    assert code == 2 and _names_the_extra(err, "search") and f"{_first_missing(*checked)} is not installed" in err


def test_search_report_without_matplotlib_exits_2_and_no_report_does_not_need_it(monkeypatch, capsys, tmp_path):
    _missing(monkeypatch, "matplotlib")
    from fem_grasp.batch.engine import require_search_extra

    if not all(importlib.util.find_spec(m) for m in ("pandas", "pyarrow")):
        pytest.skip("the search extra is not installed: its own message comes first")
    assert main(["search", "foam_block", "--workers", "0", "--out", str(tmp_path / "s"), "--no-cache"]) == 2
    assert _names_the_extra(capsys.readouterr().err, "report")
    require_search_extra(dask=False, files=True, report=False)  # without the report: matplotlib is not needed


def test_mesh_command_without_gmsh_exits_2_naming_the_mesh_extra(monkeypatch, capsys, tmp_path):
    _missing(monkeypatch, "gmsh")
    stl = write_stl(tmp_path / "ball.stl", *icosphere())
    code = main(["mesh", str(stl), "-o", str(tmp_path / "ball.vtu")])
    err = capsys.readouterr().err
    assert code == 2 and _names_the_extra(err, "mesh") and "python3-gmsh" in err
    assert not (tmp_path / "ball.vtu").exists()


def test_quick_run_without_gmsh_exits_2_naming_the_mesh_extra(monkeypatch, capsys, tmp_path):
    _missing(monkeypatch, "gmsh")
    code = main(["run", "tomato", "--quick", "--cache", str(tmp_path / "cache")])
    assert code == 2 and _names_the_extra(capsys.readouterr().err, "mesh")


def test_python_callers_get_the_same_message(monkeypatch):
    _missing(monkeypatch, "gmsh", "sksparse", "sksparse.cholmod")
    from fem_grasp.elastic import cholmod, sparse_solvers

    monkeypatch.setattr(cholmod, "_LIBRARY_TRIED", True)  # and no CHOLMOD library loads either
    monkeypatch.setattr(cholmod, "_LIBRARY", None)
    from fem_grasp.mesh import shapes

    with pytest.raises(ImportError, match=r'pip install "fem_grasp\[mesh\]"') as info:
        shapes.ellipsoid((0.01, 0.01, 0.01), 0.005)
    assert info.value.extra == "mesh"
    with pytest.raises(errors.MissingExtraError, match=r'pip install "fem_grasp\[cholmod\]"'):
        sparse_solvers.choose_solver("cholmod")


# ----------------------------------------------------------------- numba: said once, not silently slow
@pytest.fixture
def fresh_kernels(monkeypatch):
    """prepare_kernels as in a new process (it works once per process)."""
    warm_up = importlib.import_module("fem_grasp.contact.warm_up")  # the module (the package exports its function)
    monkeypatch.setattr(warm_up, "_prepared", False)
    return warm_up


def test_without_numba_one_hint_per_process_names_the_fast_extra(fresh_kernels, monkeypatch, caplog):
    from fem_grasp.contact.kernels import jit

    monkeypatch.setattr(jit, "ENABLED", False)
    _missing(monkeypatch, "numba")
    with caplog.at_level(logging.INFO, logger="fem_grasp"):
        fresh_kernels.prepare_kernels()
        fresh_kernels.prepare_kernels()
    hints = [r for r in caplog.records if "fem_grasp[fast]" in r.getMessage()]
    assert len(hints) == 1 and "5x" in hints[0].getMessage() and hints[0].levelno >= logging.INFO


def test_rest_and_pickup_prepare_the_kernels_once(fresh_kernels, caplog, box_body):
    """The first rest of a process compiles or loads the kernels (said at INFO) or, without numba, gives the hint;
    the pickup after it says nothing more."""
    from fem_grasp import pickup, rest
    from fem_grasp.contact.kernels import jit

    with caplog.at_level(logging.INFO, logger="fem_grasp"):
        state = rest(box_body, 0.5)
        pickup(box_body, mu_finger=0.5, mu_table=0.5, rest_state=state, lift=False)
    said = "contact kernels ready" if jit.ENABLED else "fem_grasp[fast]"
    assert sum(said in r.getMessage() for r in caplog.records) == 1


def test_a_slow_first_compilation_is_announced_once(fresh_kernels, monkeypatch, caplog):
    """A cold numba cache: the kernels take minutes to compile; the log says so while it happens, once."""
    from fem_grasp.contact.kernels import jit

    monkeypatch.setattr(jit, "ENABLED", True)
    monkeypatch.setattr(jit, "backend_name", lambda: "numba")
    monkeypatch.setattr(fresh_kernels, "COMPILE_NOTICE_DELAY", 0.05)
    monkeypatch.setattr(fresh_kernels, "warm_up", lambda: time.sleep(0.5) or 0.5)
    with caplog.at_level(logging.INFO, logger="fem_grasp"):
        fresh_kernels.prepare_kernels()
        fresh_kernels.prepare_kernels()
    notices = [r for r in caplog.records if "compiling" in r.getMessage()]
    assert len(notices) == 1 and notices[0].levelno == logging.WARNING and "once" in notices[0].getMessage()


def test_a_cached_load_is_not_announced(fresh_kernels, monkeypatch, caplog):
    from fem_grasp.contact.kernels import jit

    monkeypatch.setattr(jit, "ENABLED", True)
    monkeypatch.setattr(jit, "backend_name", lambda: "numba")
    monkeypatch.setattr(fresh_kernels, "COMPILE_NOTICE_DELAY", 0.3)
    monkeypatch.setattr(fresh_kernels, "warm_up", lambda: 0.0)
    with caplog.at_level(logging.INFO, logger="fem_grasp"):
        fresh_kernels.prepare_kernels()
        time.sleep(0.6)  # past the delay: the notice thread has seen the warm-up end
    assert not any("compiling" in r.getMessage() for r in caplog.records)
