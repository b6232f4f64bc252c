"""Output folders kept safe: the executor is reached before anything is deleted, one writer per
folder (a lock, taken over from a killed holder), folders that are not navsim's refused, only
files navsim wrote (and that did not change since) removed, SIGTERM handled as Ctrl-C with
the workers ending with their parent, a full disk reported as such, strict JSON."""

import dataclasses
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import navsim
from navsim.cli import main
from navsim.foundations.errors import NavsimError
from navsim.foundations.outputs import MANIFEST, OutputFolder

TINY = """
name: tiny_safety
description: a 60 s P0-like flight for the output-safety tests
aircraft: survey10
track:
  start: {lat_deg: 30.0, lon_deg: 122.5, alt_m: 150, speed_mps: 15, heading_deg: 0}
  segments:
    - {type: straight, time_s: 30}
    - {type: turn, by_deg: 90, bank_deg: 20}
    - {type: straight, time_s: 20}
sensors:
  imu: {model: p0_imu}
  bd: {model: p0_bd2}
  ads: {model: p0_ads}
estimators:
  - {label: free SINS, type: sins}
  - label: KF
    type: eskf
    states: p0_16
    period_s: 1.0
    noise: {imu: p0_imu}
    baro: {sigma_m: 3.0, tau_s: 600}
    measurements:
      - {type: gnss_position, sensor: bd, sigma_m: [8, 8, 8]}
      - {type: velocity, sensor: ads, sigma_mps: [1.0, 1.0, 1.5]}
      - {type: height, sensor: ads, field: h_pressure_m, sigma_m: 1.0, baro_state: true}
initial_errors: {pos_m: [5, 5, 10], vel_mps: 0.1, att_arcsec: [20, 20, 50]}
montecarlo: {runs: 2, seed: 1, workers: 1}
metrics:
  settle_s: 10
report: {formats: [pdf]}
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny scenario's file and a finished run of it (``(scenario, folder)``)."""
    root = tmp_path_factory.mktemp("tiny")
    os.environ.setdefault("NAVSIM_CACHE", str(root / "cache"))
    path = root / "tiny.yaml"
    path.write_text(TINY)
    assert main(["run", str(path), "--out", str(root / "done")]) == 0
    return path, root / "done"


def finished_copy(tiny, dest: Path) -> Path:
    shutil.copytree(tiny[1], dest)
    return dest


def listing(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def release(folder: OutputFolder, clear: bool = False):
    """``folder.clear_earlier()`` if ``clear``, then its lock given back; returns what was cleared."""
    removed = folder.clear_earlier() if clear else None
    getattr(folder, "close", lambda: None)()
    return removed


def need_distributed():
    """Dask distributed, or a skip (a failure in CI: NAVSIM_REQUIRE_DASK=1, where ``.ci/run``
    runs the tests marked ``dask`` with the extra installed)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        if os.environ.get("NAVSIM_REQUIRE_DASK") == "1":
            pytest.fail("NAVSIM_REQUIRE_DASK=1 but Dask distributed is not installed")
        pytest.skip("needs pip install -e '.[dask]'")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# --- 1. the executor before anything is deleted ---------------------------------------------------


@pytest.mark.dask
def test_an_unreachable_scheduler_deletes_nothing(tiny, tmp_path, monkeypatch, capsys):
    need_distributed()
    from navsim.experiment import executors
    monkeypatch.setattr(executors, "CONNECT_TIMEOUT_S", 2, raising=False)
    out = finished_copy(tiny, tmp_path / "out")
    before = listing(out)
    code = main(["run", str(tiny[0]), "--out", str(out), "--executor", "dask",
                 "--scheduler", f"tcp://127.0.0.1:{free_port()}"])
    assert code == 2, capsys.readouterr().err
    assert "cannot reach the Dask scheduler" in capsys.readouterr().err
    assert listing(out) == before                   # the finished run, untouched


@pytest.mark.dask
def test_a_server_that_is_not_dask_is_refused(tiny, tmp_path, capsys):
    need_distributed()
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    server.settimeout(20)

    def serve():                               # garbage for each connection, then closed
        for _ in range(4):
            try:
                conn, _ = server.accept()
            except OSError:
                return
            with conn:
                conn.sendall(b"\xff" * 64 + b"HTTP/1.0 200 OK\r\n\r\nnot dask\n" * 8)
                time.sleep(0.3)
    threading.Thread(target=serve, daemon=True).start()
    try:
        code = main(["run", str(tiny[0]), "--out", str(tmp_path / "out"), "--executor", "dask",
                     "--scheduler", f"tcp://127.0.0.1:{server.getsockname()[1]}"])
    finally:
        server.close()
    err = capsys.readouterr().err
    assert code == 2 and "is not a Dask scheduler" in err and "Traceback" not in err, err


# --- 2. one writer per folder ---------------------------------------------------------------------

HOLD = ("import sys, time; from navsim.foundations.outputs import OutputFolder; "
        "f = OutputFolder(sys.argv[1], command='run'); print('held', flush=True); time.sleep(60)")


def test_a_second_writer_is_refused_at_once(tiny, tmp_path, capsys):
    out = finished_copy(tiny, tmp_path / "out")
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        before = listing(out)
        t0 = time.perf_counter()
        code = main(["run", str(tiny[0]), "--out", str(out), "--seed", "778"])
        err = capsys.readouterr().err
        assert code == 2 and f"pid {holder.pid}" in err and "started" in err and "in use" in err, err
        assert time.perf_counter() - t0 < 5                   # at once: nothing flown or run
        assert listing(out) == before                          # nothing touched
    finally:
        holder.kill()
        holder.wait()


def test_another_thread_of_this_process_is_refused_as_another_process_is(tmp_path):
    """Two threads of one process (a notebook's tasks) writing one folder: the second is refused
    as a second process is (the review found it let in, the mixed-seed case again)."""
    first = OutputFolder(tmp_path / "out", command="run")
    errors = []

    def second():
        try:
            OutputFolder(tmp_path / "out", command="run")
        except NavsimError as exc:
            errors.append(str(exc))
    t = threading.Thread(target=second, name="notebook-task")
    t.start()
    t.join()
    assert len(errors) == 1 and "in use" in errors[0] and "thread MainThread" in errors[0], errors
    again = OutputFolder(tmp_path / "out", command="run")  # the holding thread itself: re-entrant
    again.close()
    first.close()


def test_a_file_system_without_flock_falls_back_to_an_exclusive_create(tmp_path, monkeypatch, caplog):
    """flock raising ENOSYS (Lustre without -o flock): the lock is taken by an exclusive create,
    with a warning, and still refuses a second writer (the review found exit 4 and a lock file
    left behind)."""
    import errno
    import fcntl
    from navsim.foundations import outputs

    def no_flock(fd, op):
        raise OSError(errno.ENOSYS, "Function not implemented")
    monkeypatch.setattr(fcntl, "flock", no_flock)
    folder = OutputFolder(tmp_path / "out", command="run")
    assert "no flock" in caplog.text and (tmp_path / "out" / outputs.LOCK).is_file()
    holder = json.loads((tmp_path / "out" / outputs.LOCK).read_text())
    assert holder["pid"] == os.getpid()
    folder.close()
    assert not (tmp_path / "out" / outputs.LOCK).exists()
    (tmp_path / "held").mkdir()                      # a live holder (our parent) on this host
    (tmp_path / "held" / outputs.LOCK).write_text(json.dumps(
        {"pid": os.getppid(), "host": socket.gethostname(), "started": "earlier", "command": "navsim run"}))
    with pytest.raises(NavsimError, match=f"pid {os.getppid()}"):
        OutputFolder(tmp_path / "held", command="run")


def test_a_lock_left_by_a_killed_writer_is_taken_over(tiny, tmp_path, caplog):
    out = finished_copy(tiny, tmp_path / "out")
    dead = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True)
    assert dead.stdout.readline().strip() == "held"
    dead.kill()                                                # SIGKILL: the lock file stays
    dead.wait()
    assert (out / ".navsim.lock").is_file()
    with caplog.at_level("WARNING"):
        folder = OutputFolder(out, command="run")
        folder.text("note.txt", "x")
        release(folder)
    assert f"pid {dead.pid}" in caplog.text and "taking over" in caplog.text
    assert not (out / ".navsim.lock").exists()                 # given back


def test_the_api_holds_the_folder_while_it_runs(tiny, tmp_path):
    out = tmp_path / "api"
    tries = []

    def progress(n):
        if not tries:
            tries.append(subprocess.run([sys.executable, "-c", HOLD.replace("time.sleep(60)", "pass"), str(out)],
                                        capture_output=True, text=True, timeout=60))
    navsim.run(tiny[0], runs=2, out=out, progress=progress)
    assert tries and tries[0].returncode != 0 and "in use by another navsim writer" in tries[0].stderr
    assert f"pid {os.getpid()}" in tries[0].stderr
    outer = OutputFolder(out, command="run")  # given back, and re-entrant
    release(OutputFolder(out, command="run"))
    release(outer)


# --- 3. folders that are not navsim's ------------------------------------------------------------


def test_a_folder_that_is_not_navsims_is_refused_unless_forced(tiny, tmp_path, capsys):
    mine = tmp_path / "mine"
    (mine / "chunks").mkdir(parents=True)
    (mine / "metrics.json").write_text('{"mine": true}')
    (mine / "chunks" / "data.bin").write_bytes(b"1")
    names = [f"note{i}.txt" for i in range(6)]
    for name in names:
        (mine / name).write_text("x")
    before = listing(mine)
    assert main(["run", str(tiny[0]), "--out", str(mine)]) == 2
    err = capsys.readouterr().err
    assert "not a navsim output folder" in err and "metrics.json" in err and "chunks/" in err, err
    assert "and 3 more" in err and "--force" in err
    assert listing(mine) == before and sorted(os.listdir(mine)) == sorted(["chunks", "metrics.json", *names])
    assert main(["run", str(tiny[0]), "--out", str(mine), "--force"]) == 0
    assert json.loads((mine / "metrics.json").read_text())["runs"] == 2


def test_empty_missing_and_navsim_folders_are_written(tmp_path):
    (tmp_path / "empty").mkdir()
    (tmp_path / "parent" / "flight").mkdir(parents=True)
    (tmp_path / "parent" / "flight" / MANIFEST).write_text('{"format": 2, "files": {}}')
    for path in (tmp_path / "empty", tmp_path / "new" / "deeper", tmp_path / "parent"):
        folder = OutputFolder(path, command="run")
        folder.text("a.txt", "a")
        release(folder)


# --- 4. only the files navsim wrote, unchanged, are removed --------------------------------------


def test_a_planted_manifest_deletes_nothing(tmp_path, caplog):
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "thesis.tex").write_text("years of work")
    (folder / MANIFEST).write_text(json.dumps(["thesis.tex"]))        # an old-style manifest
    with pytest.raises(NavsimError, match=r"an earlier navsim command .*\(thesis.tex\)"):
        OutputFolder(folder, command="run")         # listed, whose command it cannot tell: not free
    assert (folder / "thesis.tex").read_text() == "years of work"


def test_a_file_changed_since_navsim_wrote_it_is_kept(tmp_path):
    folder = tmp_path / "out"
    out = OutputFolder(folder, command="run")
    out.text("metrics.json", "{}")
    out.text("run.json", "{}")
    release(out)
    (folder / "metrics.json").unlink()
    (folder / "metrics.json").write_text("the user's own, under the same name")
    target = tmp_path / "victim.txt"
    target.write_text("elsewhere")
    (folder / "run.json").unlink()
    (folder / "run.json").symlink_to(target)
    release(OutputFolder(folder, command="run"), clear=True)
    assert (folder / "metrics.json").read_text() == "the user's own, under the same name"
    assert (folder / "run.json").is_symlink() and target.read_text() == "elsewhere"
    out = OutputFolder(folder, command="run")  # what navsim wrote goes
    out.text("report.txt", "r")
    release(out)
    assert release(OutputFolder(folder, command="run"), clear=True) == ["report.txt"]


# --- 5. SIGTERM, SIGKILL and the workers ----------------------------------------------------------


def children(pid: int) -> set:
    """The pids of the processes whose parent is ``pid`` (Linux /proc)."""
    out = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.add(int(entry))
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def start_long_run(scenario, out):
    proc = subprocess.Popen([sys.executable, "-m", "navsim", "run", str(scenario), "--out", str(out),
                             "--runs", "60", "--chunk-runs", "2", "--workers", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        index = out / "chunks" / "index.json"
        try:
            if json.loads(index.read_text()).get("chunks"):
                workers = children(proc.pid)
                if len(workers) >= 2:
                    return proc, workers
        except (OSError, ValueError):
            pass
        if proc.poll() is not None:
            pytest.fail(f"the run ended early: {proc.communicate()}")
        time.sleep(0.05)
    proc.kill()
    pytest.fail("no chunk finished in 120 s")


def wait_gone(pids, seconds: float) -> set:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.1)
    return {p for p in pids if alive(p)}


def kill_all(pids):
    for p in pids:
        if alive(p):
            os.kill(p, signal.SIGKILL)


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_sigterm_keeps_the_finished_chunks_and_ends_the_workers(tiny, tmp_path):
    out = tmp_path / "out"
    proc, workers = start_long_run(tiny[0], out)
    try:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 143, err
        assert "terminated" in err and "Traceback" not in err, err
        index = json.loads((out / "chunks" / "index.json").read_text())
        assert index["chunks"] and all((out / "chunks" / f).is_file() for f in index["chunks"].values())
        assert json.loads((out / "metrics.json").read_text())["interrupted"] is True
        assert not wait_gone(workers, 5)
    finally:
        proc.kill()
        kill_all(workers)


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_sigkill_ends_the_workers_and_resume_completes(tiny, tmp_path):
    out = tmp_path / "out"
    proc, workers = start_long_run(tiny[0], out)
    try:
        proc.kill()
        proc.communicate(timeout=30)
        assert not wait_gone(workers, 5), "worker processes outlived their killed parent"
    finally:
        kill_all(workers)
    r = subprocess.run([sys.executable, "-m", "navsim", "run", str(tiny[0]), "--out", str(out), "--runs", "60",
                        "--chunk-runs", "2", "--workers", "2", "--resume"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert "taking over the lock" in r.stderr
    assert json.loads((out / "metrics.json").read_text())["runs_done"] == 60


# --- 6. a full disk while the report is written ---------------------------------------------------


def test_a_full_disk_in_report_pdf_is_exit_4(tiny, tmp_path, monkeypatch, capsys):
    from navsim.report import render
    save_pdf = render._save_pdf

    def onto_a_full_disk(path, data):            # a file whose writes meet ENOSPC
        save_pdf("/dev/full", data)
    monkeypatch.setattr(render, "_save_pdf", onto_a_full_disk)
    code = main(["run", str(tiny[0]), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 4 and "report.pdf" in err and "No space left on device" in err, err
    assert not (tmp_path / "out" / "report.pdf").exists()


# --- 7. strict JSON -------------------------------------------------------------------------------


def strict(text: str):
    def refuse(name):
        raise ValueError(f"{name} is not JSON")
    return json.loads(text, parse_constant=refuse)


def test_metrics_json_is_strict_and_reads_back_nan(tiny, tmp_path):
    result = navsim.run(tiny[0], runs=2)
    kf = result.metrics.estimators["KF"]
    result.metrics.estimators["KF"] = dataclasses.replace(
        kf, rms=dataclasses.replace(kf.rms, pos_m=[math.nan, 1.0, math.inf]))
    result.record.wall_s = math.nan
    navsim.write_report(result, tmp_path / "out")
    metrics = strict((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["estimators"]["KF"]["rms"]["pos_m"] == [None, 1.0, None]
    assert strict((tmp_path / "out" / "run.json").read_text())["wall_s"] is None
    back = navsim.open_result(tmp_path / "out").metrics.estimators["KF"].rms.pos_m
    assert math.isnan(back[0]) and back[1] == 1.0 and math.isnan(back[2])


def contents(folder: Path) -> dict:
    """Every file under ``folder``, byte for byte (the lock aside: it comes and goes)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".navsim.lock"}


@pytest.fixture(scope="module")
def three_results(tiny, tmp_path_factory):
    """A finished run, an interrupted one (a chunk and no metrics) and a write_report folder."""
    root = tmp_path_factory.mktemp("three")
    done = finished_copy(tiny, root / "done")
    cut = finished_copy(tiny, root / "cut")
    for name in ("metrics.json", "report.pdf"):
        (cut / name).unlink()
    result = navsim.run(tiny[0], runs=2, seed=3, workers=1)
    navsim.write_report(result, root / "written")
    assert (root / "written" / "runs.npz").is_file()
    return {"run": done, "interrupted run": cut, "write_report": root / "written"}


@pytest.mark.parametrize("holder", ["run", "interrupted run", "write_report"])
@pytest.mark.parametrize("command", ["compare", "budget", "sweep", "fly", "sensors"])
def test_another_command_into_a_runs_folder_is_refused_and_deletes_nothing(tiny, three_results, tmp_path,
                                                                         capsys, holder, command):
    """Issue 50's data loss: `compare A B --out C` and `budget S --out C` deleted C's run."""
    folder = tmp_path / "c"
    shutil.copytree(three_results[holder], folder, copy_function=shutil.copy2)
    before = contents(folder)
    sweep = tmp_path / "s.yaml"
    shutil.copyfile(tiny[0], tmp_path / "tiny.yaml")
    sweep.write_text("scenario: tiny.yaml\nruns: 2\nmetric: rms.pos_m\ngrid: {montecarlo.seed: [1]}\n")
    argv = {"compare": ["compare", str(tiny[1]), str(tiny[1]), "--estimators", "free SINS", "KF"],
            "budget": ["budget", str(tiny[0]), "--runs", "2"], "sweep": ["sweep", str(sweep)],
            "fly": ["fly", str(tiny[0])], "sensors": ["sensors", str(tiny[0]), "--runs", "1"]}[command]
    assert main([*argv, "--out", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "holds the result of `navsim run`" in err and f"`navsim {command}`" in err and "Traceback" not in err
    assert contents(folder) == before


def test_the_api_refuses_to_write_a_run_into_a_comparisons_folder(tiny, tmp_path, capsys):
    out = tmp_path / "cmp"
    assert main(["compare", str(tiny[1]), "--estimators", "free SINS", "KF", "--out", str(out)]) == 0
    before = contents(out)
    with pytest.raises(NavsimError, match="holds the result of `navsim compare`"):
        navsim.run(tiny[0], runs=2, seed=1, workers=1, out=out)
    assert contents(out) == before


def test_the_same_command_again_replaces_only_its_own_files_and_a_fresh_budget_warns_of_nothing(
        tiny, tmp_path, caplog):
    out = tmp_path / "b"
    budget = ["budget", str(tiny[0]), "--method", "covariance", "--out", str(out)]     # its pages, not its runs
    with caplog.at_level("WARNING"):
        assert main(budget) == 0
    assert not [r for r in caplog.records if "left" in r.getMessage()], caplog.text
    mine = out / "notes.txt"
    mine.write_text("the user's")
    assert main(budget) == 0
    assert mine.read_text() == "the user's" and (out / "budget.json").is_file()
    assert json.loads((out / MANIFEST).read_text())["command"] == "budget"


def test_a_result_being_written_is_named_as_such(tiny, tmp_path):
    folder = finished_copy(tiny, tmp_path / "busy")
    (folder / "metrics.json").unlink()
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from navsim.foundations.outputs import "
                               "OutputFolder; f = OutputFolder(sys.argv[1], command='run'); print('held', flush=True);"
                               " time.sleep(60)", str(folder)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        for read in (navsim.open_result, lambda f: navsim.compare(f, f)):
            with pytest.raises(NavsimError, match=f"being written by another navsim \\(pid {holder.pid}"):
                read(folder)
    finally:
        holder.kill()
        holder.wait()
    with pytest.raises(NavsimError, match="not a finished navsim run.*metrics.json"):
        navsim.open_result(folder)


def _manifest(folder: Path, data) -> None:
    folder.mkdir(parents=True)
    (folder / MANIFEST).write_text(json.dumps(data))


@pytest.mark.parametrize("files, holder", [(["budget_part_all.npz"], "budget"), (["compare.json", "compare.pdf"], "compare"),
                                           (["sensor_imu.png"], "sensors"), (["metrics.json", "run.json"], "run")])
def test_a_folder_of_an_older_navsim_is_told_by_its_files_and_kept(tmp_path, files, holder):
    """A format-2 manifest (navsim 0.3.0) names no command: its files tell which (an interrupted
    budget's parts among them), and another command is refused without touching them."""
    folder = tmp_path / "old"
    _manifest(folder, {"format": 2, "files": {}})
    for name in files:
        (folder / name).write_text(name)
    st = {n: os.lstat(folder / n) for n in files}
    ident = {n: {"size": s.st_size, "mtime_ns": s.st_mtime_ns, "ino": s.st_ino, "dev": s.st_dev} for n, s in st.items()}
    (folder / MANIFEST).write_text(json.dumps({"format": 2, "files": ident}))
    other = "fly" if holder != "fly" else "run"
    with pytest.raises(NavsimError, match=f"holds the result of `navsim {holder}`"):
        OutputFolder(folder, command=other)
    assert sorted(os.listdir(folder)) == sorted([*files, MANIFEST])
    release(OutputFolder(folder, command=holder), clear=True)          # its own command replaces them
    assert not any((folder / n).exists() for n in files)


def test_a_manifest_that_cannot_tell_or_names_a_newer_command_is_refused(tmp_path):
    untold = tmp_path / "untold"
    _manifest(untold, ["notes.csv"])
    (untold / "notes.csv").write_text("x")
    with pytest.raises(NavsimError, match="an earlier navsim command"):
        OutputFolder(untold, command="compare")
    newer = tmp_path / "newer"
    _manifest(newer, {"format": 4, "command": "tune", "files": {"tune.json": None}})
    (newer / "tune.json").write_text("{}")
    with pytest.raises(NavsimError, match="`navsim tune`"):
        OutputFolder(newer, command="run")
    assert (untold / "notes.csv").exists() and (newer / "tune.json").exists()


def test_a_result_whose_files_are_gone_leaves_its_folder_free(tmp_path):
    folder = tmp_path / "gone"
    _manifest(folder, {"format": 3, "command": "budget", "files": {"budget.json": None}})
    release(OutputFolder(folder, command="compare"), clear=True)
    assert json.loads((folder / MANIFEST).read_text())["command"] == "compare"


def test_this_process_reentering_with_another_command_is_refused(tmp_path):
    with OutputFolder(tmp_path / "f", command="budget"):
        with pytest.raises(NavsimError, match="holds the result of `navsim budget`"):
            OutputFolder(tmp_path / "f", command="run")


def test_a_budget_store_must_be_a_budgets_folder_and_a_report_not_another_runs(tiny, tmp_path):
    with OutputFolder(tmp_path / "r", command="run") as folder:
        with pytest.raises(NavsimError, match="opened for a budget"):
            navsim.budget(tiny[0], runs=2, store=folder)
    other = navsim.run(tiny[0], runs=2, seed=9, workers=1)
    target = finished_copy(tiny, tmp_path / "done")
    before = contents(target)
    with pytest.raises(NavsimError, match="holds the result of another run"):
        navsim.write_report(other, target)
    assert contents(target) == before
