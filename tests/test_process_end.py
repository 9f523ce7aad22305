"""A command that ends by itself ends like a stopped one (issue 40): ``end_process`` joins its
threads (a thread pool told to stop first, as the interpreter does), runs the ``atexit``
handlers, flushes the streams and exits with the status — without the interpreter's teardown."""
from __future__ import annotations

import subprocess
import sys
import textwrap


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=120, check=False)


def test_end_process_flushes_runs_atexit_and_joins_threads():
    done = _run("""
        import atexit, concurrent.futures, sys, threading, time
        from nhgait.gaits.cli.stopping import end_process
        atexit.register(lambda: print("atexit ran", flush=True))
        pool = concurrent.futures.ThreadPoolExecutor(1)          # never shut down by its owner
        pool.submit(lambda: None).result()
        worker = threading.Thread(target=lambda: (time.sleep(0.2), print("thread finished")))
        worker.start()
        print("buffered, not flushed", end="")
        sys.stderr.write("on stderr")
        end_process(7)
        print("never printed")
    """)
    assert done.returncode == 7, done.stderr
    assert "thread finished" in done.stdout            # a non-daemon thread is waited for
    assert "atexit ran" in done.stdout
    assert "buffered, not flushed" in done.stdout
    assert "never printed" not in done.stdout
    assert done.stderr == "on stderr"


def test_the_command_exits_with_its_status_and_its_output(tmp_path):
    """``nhgait`` run as the program: its output whole, the status of the command (2: bad input)."""
    done = subprocess.run([sys.executable, "-m", "nhgait.gaits.cli.main", "plan", "no_such_robot", "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2
    assert "'no_such_robot' is neither a scene file nor a built-in scene" in done.stderr
