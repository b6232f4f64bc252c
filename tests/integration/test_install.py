"""navsim installed, not only imported from its checkout: the wheel carries its data (the
aircraft, the sensor catalog, the tracks), read through importlib.resources; the git revision
recorded is the checkout's only; an unusable cache folder falls back to no cache with a warning,
never into the package; the README's test command needs no extra; the suite leaves the
checkout's reports/ alone."""

import os
import shutil
import subprocess
import sys
import zipfile
from importlib import resources
from pathlib import Path

import pytest

import navsim

#: what the wheel is built from (copied to tmp_path: a build in the checkout writes build/ there)
WHEEL_SOURCES = ("pyproject.toml", "README.md", "navsim", "aircraft", "sensors", "scenarios")
#: the package under test and the checkout it comes from (the checkout's files, not a copy's)
PACKAGE = Path(navsim.__file__).resolve().parent
CHECKOUT = PACKAGE.parent
#: the short scenario .ci/run runs from the wheel (this test file's checkout)
WHEEL_CHECK = Path(__file__).resolve().parents[2] / ".ci" / "wheel_check.yaml"


def build_wheel(dest: Path) -> Path:
    """The wheel of the checkout, built without build isolation from a copy in ``dest``."""
    src = dest / "src"
    src.mkdir(parents=True)
    for name in WHEEL_SOURCES:
        if (CHECKOUT / name).is_dir():
            shutil.copytree(CHECKOUT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(CHECKOUT / name, src / name)
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
                           "-q", "-w", str(dest / "dist"), str(src)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (wheel,) = (dest / "dist").glob("navsim-*.whl")
    return wheel


def test_the_wheel_holds_the_aircraft_the_catalog_the_tracks_and_every_module(tmp_path):
    """Every module of navsim/, every file of aircraft/ and every datasheet of sensors/ (as
    ``navsim/data/...``) and every track: a package missing from pyproject.toml's list, or data
    left out of the wheel, fails here."""
    names = set(zipfile.ZipFile(build_wheel(tmp_path)).namelist())
    want = {str(p.relative_to(CHECKOUT)) for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts}
    want |= {f"navsim/tracks/{p.name}" for p in (PACKAGE / "tracks").glob("*.yaml")}
    want |= {f"navsim/cli/templates/{p.name}" for p in (PACKAGE / "cli" / "templates").glob("*.txt")}
    for folder in ("aircraft", "sensors", "scenarios"):
        want |= {f"navsim/data/{p.relative_to(CHECKOUT)}" for p in (CHECKOUT / folder).rglob("*")
                 if p.is_file() and "__pycache__" not in p.parts and p.suffix in (".xml", ".yaml", ".md", ".py")}
    assert "navsim/data/aircraft/survey10/survey10.xml" in want and "navsim/data/sensors/p0_imu.yaml" in want
    assert "navsim/data/scenarios/p0_bd_sins_ads.yaml" in want and "navsim/cli/templates/estimator.py.txt" in want
    assert not want - names, sorted(want - names)


def test_the_shipped_data_is_read_through_importlib_resources():
    """The aircraft, the catalog and the tracks are the resources of navsim's packages (a real
    folder each, as JSBSim needs), not folders found beside the source tree."""
    from navsim.flight.properties import AIRCRAFT_DIR
    from navsim.flight.track import TRACKS_DIR, available_tracks
    from navsim.sensors.catalog import CATALOG_DIR
    assert AIRCRAFT_DIR == resources.files("navsim.data.aircraft")
    assert (AIRCRAFT_DIR / "survey10" / "survey10.xml").is_file()
    assert CATALOG_DIR == resources.files("navsim.data.sensors") and (CATALOG_DIR / "p0_imu.yaml").is_file()
    assert TRACKS_DIR == resources.files("navsim") / "tracks" and "p0" in available_tracks()


@pytest.mark.slow
def test_the_installed_wheel_runs_a_scenario_from_outside_the_checkout(tmp_path):
    """The wheel in a virtual environment (its dependencies those of this Python): ``navsim
    list``, ``validate`` of a shipped scenario (track and datasheets from the package) and
    ``.ci/wheel_check.yaml`` run from a folder outside the checkout; no compiled kernel lands
    in the installed package and no git revision is claimed."""
    import json
    wheel = build_wheel(tmp_path)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    subprocess.run([venv / "bin" / "python", "-m", "pip", "install", "-q", "--no-deps", "--no-index", wheel],
                   check=True)
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(WHEEL_CHECK, work)
    shutil.copy(CHECKOUT / "scenarios" / "p0_bd_sins_ads.yaml", work)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(NAVSIM_CACHE=str(tmp_path / "cache"), MPLCONFIGDIR=str(tmp_path / "mpl"))

    def navsim_(*argv):
        proc = subprocess.run([venv / "bin" / "navsim", *argv], cwd=work, env=env, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        return proc.stdout
    where = subprocess.run([venv / "bin" / "python", "-c", "import navsim; print(navsim.__file__)"], cwd=work,
                           env=env, capture_output=True, text=True, check=True).stdout
    assert Path(where.strip()).is_relative_to(venv), where
    assert "survey10" in navsim_("list") and "p0_imu" in navsim_("list")
    navsim_("validate", "p0_bd_sins_ads.yaml")
    navsim_("run", "wheel_check.yaml", "--runs", "2", "--workers", "1", "--out", "out")
    record = json.loads((work / "out" / "run.json").read_text())
    assert record["runs_done"] == 2 and record["git_revision"] is None
    assert not list(venv.rglob("*.nbi")) and list((tmp_path / "cache" / "numba").rglob("*.nbi"))


def git(*argv, cwd):
    subprocess.run(["git", "-c", "user.email=t@example.org", "-c", "user.name=t", *argv], cwd=cwd, check=True,
                   capture_output=True)


def fake_install(site: Path):
    """navsim's provenance module (the one under test) at ``site/navsim``, as an install puts it."""
    (site / "navsim" / "foundations").mkdir(parents=True)
    for name in ("__init__.py", "foundations/__init__.py"):
        (site / "navsim" / name).write_text("")
    for name in ("version.py", "foundations/provenance.py"):
        shutil.copy(PACKAGE / name, site / "navsim" / name)


def revision(site: Path) -> str:
    return subprocess.run([sys.executable, "-c", "from navsim.foundations.provenance import git_revision; "
                           "print(git_revision())"], env=dict(os.environ, PYTHONPATH=str(site)), cwd=site,
                          capture_output=True, text=True, check=True).stdout.strip()


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_the_git_revision_is_the_checkouts_only(tmp_path):
    """A package installed inside some repository (a virtual environment in a checkout, its
    site-packages ignored) claims no revision; a checkout's package gives its commit."""
    repo = tmp_path / "repo"
    repo.mkdir()
    git("init", "-q", cwd=repo)
    (repo / ".gitignore").write_text(".venv/\n")
    fake_install(repo)                                          # the checkout's own navsim
    git("add", "-A", cwd=repo)
    git("commit", "-q", "-m", "x", cwd=repo)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True).stdout.strip()
    site = repo / ".venv" / "lib" / "site-packages"
    fake_install(site)
    assert revision(site) == "None"
    assert revision(repo) == head


# --- the cache --------------------------------------------------------------------------------

#: ``navsim list``, then one of navsim's cached kernels compiled, then where numba caches
LIST_AND_COMPILE = ("from navsim.cli import main; assert main(['list']) == 0; "
                    "from navsim.navigation.kernels.earth import radii; radii(0.5); "
                    "import navsim.foundations.compiled as c; print('cache:', c.CACHE_FOLDER)")


def numba_files() -> set:
    return {p for p in PACKAGE.rglob("*") if p.suffix in (".nbi", ".nbc")}


def navsim_env(tmp_path, **values) -> dict:
    """The environment of a subprocess: no NUMBA_CACHE_DIR (tests/conftest.py sets one), the
    ``values`` given (``None``: unset)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NAVSIM_CACHE")}
    env["MPLCONFIGDIR"] = str(tmp_path / "mpl")
    env.update({k: v for k, v in values.items() if v is not None})
    for k in [k for k, v in values.items() if v is None]:
        env.pop(k, None)
    return env


@pytest.mark.parametrize("case", ["NAVSIM_CACHE through a file", "HOME a file, NAVSIM_CACHE unset"])
def test_an_unusable_cache_works_uncached_with_a_warning(tmp_path, case):
    """``--help`` and ``list`` exit 0 with a warning naming the folder; a kernel compiles
    uncached and nothing of numba's lands in the package (as root, numba would otherwise fall
    back to ``__pycache__`` beside navsim's sources)."""
    (tmp_path / "afile").write_text("a file, not a folder")
    env = navsim_env(tmp_path, **({"NAVSIM_CACHE": str(tmp_path / "afile" / "sub")} if case.startswith("NAVSIM")
                                  else {"HOME": str(tmp_path / "afile"), "NAVSIM_CACHE": None}))
    before = numba_files()
    for argv in (["-m", "navsim", "--help"], ["-c", LIST_AND_COMPILE]):
        proc = subprocess.run([sys.executable, *argv], env=env, cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
        assert "afile" in proc.stderr and "without the numba cache" in proc.stderr, proc.stderr
    assert "survey10" in proc.stdout and "cache: None" in proc.stdout, proc.stdout
    assert numba_files() == before, sorted(numba_files() - before)
    assert {p.name for p in tmp_path.iterdir()} <= {"afile", "mpl"}      # nothing cached here


def test_an_empty_navsim_cache_is_refused(tmp_path):
    """``NAVSIM_CACHE=""`` (which would cache in the current folder): ``--help`` still works, a
    run is refused with exit 2 naming the variable, nothing is cached in the current folder."""
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(WHEEL_CHECK, work)
    env = navsim_env(tmp_path, NAVSIM_CACHE="")
    assert subprocess.run([sys.executable, "-m", "navsim", "--help"], env=env, cwd=work,
                          capture_output=True).returncode == 0
    proc = subprocess.run([sys.executable, "-m", "navsim", "run", "wheel_check.yaml", "--workers", "1", "--out",
                           str(tmp_path / "out")],
                          env=env, cwd=work, capture_output=True, text=True)
    assert proc.returncode == 2 and "NAVSIM_CACHE is set but empty" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert sorted(p.name for p in work.iterdir()) == ["wheel_check.yaml"]


def test_cache_dir_says_when_it_is_unusable(tmp_path, monkeypatch, caplog):
    from navsim.foundations.config import cache_dir
    from navsim.foundations.errors import UsageError
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    assert cache_dir("flights") == tmp_path / "cache" / "flights" and (tmp_path / "cache" / "flights").is_dir()
    (tmp_path / "afile").write_text("")
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "afile" / "cache"))
    assert cache_dir("flights") is None and "without the flights cache" in caplog.text
    monkeypatch.setenv("NAVSIM_CACHE", " ")
    with pytest.raises(UsageError, match="NAVSIM_CACHE is set but empty"):
        cache_dir("flights")


# --- the suite itself -------------------------------------------------------------------------

def test_the_readme_suite_skips_the_dask_tests_without_dask(tmp_path):
    """The README's ``pip install -e ".[test]"`` has no Dask: with ``distributed`` not
    importable, every test of test_streaming.py that uses the Dask executor is skipped, none
    fails (the checkout's own test file)."""
    hide = tmp_path / "hide" / "distributed"
    hide.mkdir(parents=True)
    (hide / "__init__.py").write_text("raise ImportError('hidden by test_install.py')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [str(hide.parent), os.environ.get("PYTHONPATH")] if p))
    env.pop("NAVSIM_REQUIRE_DASK", None)
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                           "-k", "dask or executor",
                           str(CHECKOUT / "tests" / "integration" / "test_streaming.py")],
                          env=env, cwd=CHECKOUT, capture_output=True, text=True)
    assert proc.returncode == 0 and "failed" not in proc.stdout and " skipped" in proc.stdout, proc.stdout[-3000:]


def test_a_session_that_writes_into_reports_fails_in_ci(tmp_path):
    """tests/conftest.py's session-finish check (the checkout's own conftest, in a copy of the
    checkout's layout): a test leaving a folder in reports/ fails the session under
    NAVSIM_REQUIRE_CLEAN_CHECKOUT=1 and is named."""
    root = tmp_path / "checkout"
    (root / "tests").mkdir(parents=True)
    (root / "reports").mkdir()
    for name in ("conftest.py", "pages.py"):                    # the conftest and the page checker it loads
        shutil.copy(CHECKOUT / "tests" / name, root / "tests" / name)
    (root / "scenarios").symlink_to(CHECKOUT / "scenarios")
    (root / "tests" / "test_leak.py").write_text(
        "from pathlib import Path\n\ndef test_leak():\n"
        "    (Path(__file__).parents[1] / 'reports' / 'bad').mkdir()\n")
    env = dict(os.environ, NAVSIM_REQUIRE_CLEAN_CHECKOUT="1")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
                           str(root / "tests" / "test_leak.py")], env=env, cwd=root, capture_output=True, text=True)
    assert proc.returncode == 1 and "1 passed" in proc.stdout and "reports" in proc.stdout and "bad" in proc.stdout, \
        proc.stdout[-3000:]
