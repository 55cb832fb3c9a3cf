"""The console script ends the process fast (``flightid.cli.main.console_main``: flush, the
``atexit`` handlers, ``os._exit``) and loses nothing by it: exit statuses, the whole stdout
through a pipe, a closed pipe, the result folder's lock and temporary folder, numba's disk
cache. Each check runs the command in a fresh process, as a user does."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from test_cli_safety import _leftovers, _old_run, _small_case
from test_compile_cache import case_file  # noqa: F401  (fixture)

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    # stdout buffered, as users have it (a test machine may set PYTHONUNBUFFERED)
    env.pop("PYTHONUNBUFFERED", None)
    env.pop("FLIGHTID_NORMAL_EXIT", None)
    env.update(extra)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    return env


def _flightid(*argv: str, **kwargs) -> subprocess.CompletedProcess:
    """``flightid ARGV`` through the console script, stdout and stderr captured (pipes)."""
    return subprocess.run(
        [sys.executable, "-m", "flightid.cli.main", *argv],
        capture_output=True,
        text=True,
        timeout=300,
        env=_env(),
        **kwargs,
    )


def _script(code: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=300,
        env=_env(**kwargs.pop("env", {})),
        **kwargs,
    )


# ------------------------------------------------------------------ exit statuses


@pytest.mark.parametrize(
    ("argv", "status"),
    [(["--version"], 0), (["run"], 2), (["run", "no_such_case.toml"], 1), ([], 2)],
)
def test_exit_status_is_kept(argv, status):
    done = _flightid(*argv)
    assert done.returncode == status, done.stderr
    if status == 0:
        assert done.stdout.startswith("flightid ")
    if status == 1:
        assert done.stderr.strip().splitlines()[-1].startswith("flightid: error: ")


def test_interrupt_is_130():
    done = _script(
        "import flightid.cli.main as m\n"
        "def interrupted():\n"
        "    raise KeyboardInterrupt\n"
        "m.build_parser = interrupted\n"
        "m.console_main()\n"
    )
    assert done.returncode == 130
    assert done.stderr == "flightid: interrupted\n"


@pytest.mark.parametrize(("code", "status"), [("None", 0), ("3", 3), ("'gone'", 1)])
def test_system_exit_codes_become_the_status(code, status):
    done = _script(f"from flightid.cli.main import exit_now\nexit_now({code})\n")
    assert done.returncode == status
    assert done.stderr == ("gone\n" if status == 1 else "")


def test_atexit_handlers_run_and_their_output_is_flushed():
    done = _script(
        "import atexit, logging, sys\n"
        "logging.basicConfig(stream=sys.stderr, format='%(message)s')\n"
        "logging.getLogger('x').warning('logged')\n"
        "atexit.register(lambda: print('from atexit'))\n"
        "from flightid.cli.main import exit_now\n"
        "print('answer', end='')\n"
        "exit_now(0)\n"
    )
    assert done.returncode == 0
    assert done.stdout == "answerfrom atexit\n"
    assert done.stderr == "logged\n"


def test_the_normal_exit_is_kept_where_asked_for():
    # the interpreter's own exit runs finalizers os._exit would skip: a __del__ at teardown
    code = (
        "import sys\n"
        "class Last:\n"
        "    def __del__(self):\n"
        "        sys.stdout.write('finalized')\n"
        "keep = Last()\n"
        "from flightid.cli.main import exit_now\n"
        "exit_now(4)\n"
    )
    fast = _script(code)
    normal = _script(code, env={"FLIGHTID_NORMAL_EXIT": "1"})
    assert (fast.returncode, fast.stdout) == (4, "")
    assert (normal.returncode, normal.stdout) == (4, "finalized")


# ------------------------------------------------------------------ stdout


def test_large_output_reaches_a_pipe_whole():
    # 3 MB, far more than a pipe holds: the reader gets every byte, the last buffer too
    done = _script(
        "import sys\n"
        "from flightid.cli.main import exit_now\n"
        "for k in range(100_000):\n"
        "    print(f'{k:08d} ' + 'x' * 21)\n"
        "sys.stdout.write('end')\n"
        "exit_now(0)\n"
    )
    assert done.returncode == 0
    lines = done.stdout.splitlines()
    assert len(lines) == 100_001 and lines[-1] == "end"
    assert lines[99_999] == f"{99_999:08d} " + "x" * 21


def test_run_json_reaches_a_pipe_whole():
    done = _flightid("run", str(WALK), "--json", "--quiet")
    assert done.returncode == 0, done.stderr
    document = json.loads(done.stdout)
    assert document["results"][0]["parameters"]


@pytest.mark.parametrize("argv", [["--version"], ["run", str(WALK), "--json", "--quiet"]])
def test_a_closed_pipe_is_exit_1_without_noise(argv):
    # the reader is gone before the command writes: no 'Exception ignored' at exit
    read, write = os.pipe()
    os.close(read)
    try:
        done = subprocess.run(
            [sys.executable, "-m", "flightid.cli.main", *argv],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
            timeout=300,
            env=_env(),
        )
    finally:
        os.close(write)
    assert done.returncode == 1
    assert "Exception ignored" not in done.stderr and "Traceback" not in done.stderr
    assert all(line.startswith("flightid: ") for line in done.stderr.splitlines()), done.stderr


# ------------------------------------------------------------------ files


def test_run_out_leaves_no_lock_and_no_temporary_folder(tmp_path):
    case = _small_case(tmp_path)
    target = tmp_path / "run"
    done = _flightid("run", str(case), "--out", str(target), "--quiet")
    assert done.returncode == 0, done.stderr
    assert json.loads((target / "results.json").read_text())["results"]
    assert _leftovers(tmp_path) == []


def test_sigint_while_writing_leaves_the_old_run_and_no_leftovers(tmp_path):
    case = _small_case(tmp_path)
    target = tmp_path / "run"
    _old_run(target)
    before = {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}
    script = (
        "import os, signal, sys, time\n"
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "import flightid.report.html as h\n"
        "real = h.write_csv\n"
        "def write_csv(run, path):\n"
        "    real(run, path)\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(30)\n"
        "h.write_csv = write_csv\n"
        "from flightid.cli.main import console_main\n"
        f"sys.argv = ['flightid', 'run', {str(case)!r}, '--out', {str(target)!r}, "
        "'--overwrite', '--quiet']\n"
        "console_main()\n"
    )
    done = _script(script, cwd=tmp_path)
    assert done.returncode == 128 + signal.SIGINT, done.stderr
    assert done.stderr.splitlines()[-1] == "flightid: interrupted"
    assert {p: p.read_bytes() for p in target.rglob("*") if p.is_file()} == before
    assert _leftovers(tmp_path) == []


# Runs the console script counting numba compilations; an atexit handler prints the count
# (the fast exit runs it), the last stdout line
_COUNTING = r"""
import atexit, json, sys
from numba.core import event

class Compiles(event.Listener):
    count = 0
    def on_start(self, ev):
        Compiles.count += 1
    def on_end(self, ev):
        pass

event.register("numba:compile", Compiles())
atexit.register(lambda: print("\n" + json.dumps({"compiles": Compiles.count})))
from flightid.cli.main import console_main
sys.argv = ["flightid", *sys.argv[1:]]
console_main()
"""


def test_numba_cache_written_by_a_run_serves_the_next(case_file, tmp_path):  # noqa: F811
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba-cache"), "FLIGHTID_KERNEL_CACHE": "1"}
    counts = []
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-c", _COUNTING, "run", str(case_file), "--json", "--quiet"],
            capture_output=True,
            text=True,
            timeout=600,
            env=_env(**env),
        )
        assert done.returncode == 0, done.stderr[-3000:]
        counts.append(json.loads(done.stdout.strip().splitlines()[-1])["compiles"])
    assert counts[0] > 0
    assert counts[1] == 0


def test_batch_on_dask_workers_ends_cleanly(tmp_path):
    # the cluster is closed by the command itself; the fast exit then finds no worker left
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    from test_batch_engine import _simulated_case

    cases = [str(_simulated_case(tmp_path, k)) for k in range(2)]
    out = tmp_path / "out"
    done = _flightid("batch", *cases, "--workers", "2", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "engine dask distributed (LocalCluster, 2 worker(s))" in done.stderr
    noise = [line for line in done.stderr.splitlines() if "WARNING" in line or "Traceback" in line]
    assert noise == []
    assert sorted(p.name for p in (out / "cases").iterdir()) == ["sim0", "sim1"]
