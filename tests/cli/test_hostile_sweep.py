"""Sweeps stopped from outside: Ctrl-C or SIGTERM to the whole process group of a parallel
sweep (as a terminal or a batch scheduler sends them), and a disk that fills during a sweep.

Each must end at once with its exit code and one line, keep every point that was reported
finished, and leave no worker process, no lock and no temporary file behind."""

from __future__ import annotations

import errno
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import CASES, REPO, run_cli, run_python

from critfric.errors import CaseError
from critfric.files import sweepfile
from critfric.files.safety import Terminated, interrupt_guard
from critfric.files.sweepfile import read_sweep

pytestmark = [pytest.mark.once,
              pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and /proc")]

REAL_FSYNC = os.fsync
STOP_BOUND = 5.0  # seconds from the signal to the exit, on a loaded 2-core machine
POINTS = 40
# slow enough points (about 0.1 s each on two workers) that the sweep is always still
# running when the signal comes, however late the test sees the first rows
SWEEP = ["sweep", "unit-square", "--nu", f"0.02:0.46:{POINTS}", "--size", "0.01",
         "--element", "P1", "-j", "2"]


def _start(tmp_path: Path, *args, preexec_fn=None) -> subprocess.Popen:
    """``python -m critfric ARGS`` in its own session and process group (the test signals
    the group, as a terminal's Ctrl-C or a scheduler does), Ctrl-C at its default action."""

    def child():
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        if preexec_fn is not None:
            preexec_fn()

    return subprocess.Popen([sys.executable, "-m", "critfric", *map(str, args)], cwd=tmp_path,
                            env={**os.environ, "PYTHONPATH": str(REPO)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=child)


def _rows(path: Path) -> list[dict]:
    try:
        return read_sweep(path)["rows"]
    except (CaseError, OSError):  # not created yet
        return []


def _group(pgid: int) -> list[str]:
    """The live (not zombie) processes of the process group ``pgid``: 'pid command'."""
    alive = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:  # gone meanwhile
            continue
        state, _, group = stat[stat.rindex(")") + 2:].split()[:3]
        if int(group) == pgid and state != "Z":
            alive.append(f"{entry.name} {stat[stat.index('(') + 1:stat.rindex(')')]}")
    return alive


def _none_left(pgid: int) -> None:
    """No process of the sweep's group is left (multiprocessing's resource tracker ends by
    itself once its parent is gone: a moment is allowed for that, none for workers)."""
    end = time.monotonic() + 2.0
    while (left := _group(pgid)) and time.monotonic() < end:
        time.sleep(0.05)
    assert left == [], f"processes left running: {left}"


def _workers(pgid: int) -> list[str]:
    """The sweep's worker processes (multiprocessing's spawned children) in group ``pgid``."""
    found = []
    for entry in _group(pgid):
        try:
            command = Path(f"/proc/{entry.split()[0]}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in command:
            found.append(entry)
    return found


def _signalled(tmp_path: Path, signum: int, *, rows: int) -> tuple:
    """Run the sweep, signal its process group once ``rows`` points are in the file (0:
    while the worker processes start, importing critfric); (exit code, stderr, seconds
    from the signal to the exit)."""
    out = tmp_path / "s.h5"
    proc = _start(tmp_path, *SWEEP, "-o", out)
    try:
        end = time.monotonic() + 120
        while not (len(_rows(out)) >= rows > 0 or rows == 0 and _workers(proc.pid)):
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < end, "no point was finished in 120 s"
            time.sleep(0.01)
        if rows == 0:
            time.sleep(0.3)  # inside the workers' imports (about 1 s)
        sent = time.monotonic()
        os.killpg(proc.pid, signum)
        _, stderr = proc.communicate(timeout=60)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    _none_left(proc.pid)
    return proc.returncode, stderr, took


@pytest.mark.parametrize("signum,code,word", [(signal.SIGINT, 130, "interrupted"),
                                              (signal.SIGTERM, 143, "terminated")],
                         ids=["SIGINT", "SIGTERM"])
def test_a_signal_to_the_group_of_a_parallel_sweep_stops_it_and_keeps_its_points(
        tmp_path, signum, code, word):
    returncode, stderr, took = _signalled(tmp_path, signum, rows=2)
    assert returncode == code, stderr
    assert took < STOP_BOUND, f"{took:.1f} s from the signal to the exit"
    assert "Traceback" not in stderr and stderr.count(f"critfric: {word}:") == 1, stderr
    assert "every finished point is kept" in stderr
    # every point said finished is in the file (one more at most: written, not yet said)
    said = len(re.findall(r"^critfric: sweep: point \d+/", stderr, re.MULTILINE))
    kept = read_sweep(tmp_path / "s.h5")["rows"]
    assert 2 <= len(kept) < POINTS and said <= len(kept) <= said + 1, stderr
    assert all(r["status"] == "ok" and r["positive"] for r in kept)
    assert len({r["nu"] for r in kept}) == len(kept)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]  # no lock, no .tmp


def test_ctrl_c_while_the_workers_start_is_130_without_a_traceback(tmp_path):
    """The signal reaches the worker processes while they import critfric: they ignore it
    (no traceback of theirs), the parent stops them."""
    returncode, stderr, took = _signalled(tmp_path, signal.SIGINT, rows=0)
    assert returncode == 130, stderr
    assert took < STOP_BOUND, f"{took:.1f} s from the signal to the exit"
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.count("critfric: interrupted") == 1
    assert all(r["status"] == "ok" for r in read_sweep(tmp_path / "s.h5")["rows"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]


def test_sigterm_under_the_guard_is_held_through_a_write_and_raised_after():
    saved, done = signal.getsignal(signal.SIGTERM), []
    with interrupt_guard() as guard:
        with pytest.raises(Terminated), guard.deferred():
            with guard.deferred():  # nested: only the outermost raises
                os.kill(os.getpid(), signal.SIGTERM)
                sum(range(10_000))  # the handler runs here, and holds it
            done.append("inner")
            done.append("write")
        with pytest.raises(Terminated):
            guard.check()  # and again at the next safe point
    assert done == ["inner", "write"]
    assert signal.getsignal(signal.SIGTERM) is saved  # restored


# ------------------------------------------------------------------------- a full disk
def _full_at(monkeypatch, writes: int, code: int = errno.ENOSPC) -> list[int]:
    """The sweep file's ``writes``-th flush to disk (and every later one) fails with
    ``code``, as on a file system that reports a full disk when the data is written out;
    returns the list the flushes are counted in."""
    count = [0]
    fsync = REAL_FSYNC

    def failing(fd):
        count[0] += 1
        if count[0] >= writes:
            raise OSError(code, os.strerror(code))
        fsync(fd)

    monkeypatch.setattr(sweepfile.os, "fsync", failing)
    return count


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EFBIG], ids=["ENOSPC", "EFBIG"])
def test_a_disk_full_while_adding_a_point_leaves_the_file_as_it_was(tmp_path, monkeypatch,
                                                                    code):
    out = tmp_path / "s.h5"
    sweep = ["sweep", CASES / "four_triangles.toml", "--nu", "0.1,0.2,0.3,0.4,0.45", "-j", "1",
             "-o", out]
    before = {}
    replace = sweepfile._replace

    def recording(path, data, what, kept):  # the file's bytes before each write
        before[len(before)] = Path(path).read_bytes() if Path(path).exists() else None
        replace(path, data, what, kept)

    monkeypatch.setattr(sweepfile, "_replace", recording)
    _full_at(monkeypatch, 4, code)  # the file, then two points, then the disk is full
    res = run_cli(*sweep)
    assert res.exit_code == 1, res.output
    lines = [line for line in res.stderr.splitlines() if not line.startswith("critfric: sweep:")]
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert lines[0].startswith("critfric: error: cannot add a point to") and \
        "the disk is full" in lines[0] and "its 2 points are safe" in lines[0], lines[0]
    assert out.read_bytes() == before[3]  # as before the failing write
    assert [r["nu"] for r in read_sweep(out)["rows"]] == [0.1, 0.2]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]
    monkeypatch.undo()  # space again: the same command computes only the rest
    res = run_cli(*sweep)
    assert res.exit_code == 0 and "3 computed now" in res.stdout, res.output
    assert [r["nu"] for r in read_sweep(out)["rows"]] == [0.1, 0.2, 0.3, 0.4, 0.45]


def test_a_disk_full_while_writing_the_limits_or_creating_the_file(tmp_path, monkeypatch):
    out = tmp_path / "s.h5"
    sweep = ["sweep", CASES / "four_triangles.toml", "--nu", "0.1,0.2", "-j", "1", "-o", out]
    _full_at(monkeypatch, 1)  # the first write: creating the file
    res = run_cli(*sweep)
    assert res.exit_code == 1 and "cannot create" in res.stderr, res.output
    assert "the disk is full" in res.stderr and "no point was computed" in res.stderr
    assert list(tmp_path.iterdir()) == []
    _full_at(monkeypatch, 4)  # the file, two points, then the limits
    res = run_cli(*sweep)
    assert res.exit_code == 1 and "write the h -> 0 limits" in res.stderr, res.output
    assert "its 2 points are safe" in res.stderr and len(_rows(out)) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]


def test_a_file_size_limit_in_a_parallel_sweep_is_exit_1_and_one_line(tmp_path):
    """A real write failing (the file-size limit, EFBIG, stands in for a full disk) while
    two workers run: exit 1, one line saying how many points are safe, that many in the
    file, no worker, lock or temporary file left."""

    def small_files():
        import resource

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the write fails instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (90_000, 90_000))

    out = tmp_path / "s.h5"
    proc = _start(tmp_path, "sweep", "unit-square", "--nu", "0:0.5:11", "-j", "2", "-o", out,
                  preexec_fn=small_files)
    try:
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    _none_left(proc.pid)
    assert proc.returncode == 1, stderr
    errors = [line for line in stderr.splitlines() if not line.startswith("critfric: sweep:")
              and not line.startswith("critfric: note:")]
    assert len(errors) == 1 and "Traceback" not in stderr, stderr
    found = re.search(r"the disk is full \(File too large\); the file is unchanged, its (\d+) "
                      r"points? (are|is) safe", errors[0])
    assert found, errors[0]
    kept = read_sweep(out)["rows"]
    assert len(kept) == int(found[1]) <= 11  # the limits, at the latest, find no room
    assert all(r["status"] in ("ok", "no-real-eigenvalue") for r in kept)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]


def test_sigterm_reaches_python_during_and_after_a_gmsh_session():
    """gmsh installs C signal handlers of its own: SIGTERM killed critfric outright (no
    message, its output lock left behind) once a mesh had been made."""
    code = ("import os, signal, time\n"
            "from critfric.meshing.mesh import _gmsh_session\n"
            "seen = []\n"
            "signal.signal(signal.SIGTERM, lambda *a: seen.append('x'))\n"
            "with _gmsh_session():\n"
            "    os.kill(os.getpid(), signal.SIGTERM); time.sleep(0.2)\n"
            "os.kill(os.getpid(), signal.SIGTERM); time.sleep(0.2)\n"
            "print(len(seen))\n")
    out = run_python(code)
    assert out.returncode == 0 and out.stdout.split() == ["2"], (out.returncode, out.stderr)
