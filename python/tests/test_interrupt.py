"""Ctrl-C during a run stops it at the end of an iteration with its checkpoint, raises
KeyboardInterrupt with the library's words, and the run resumes to the same bits as an
uninterrupted one; the same Python process then runs again (the library's stop flag is
withdrawn when the next run starts). Each interrupted run is its own Python process, so the
signal reaches no other test."""

import subprocess
import sys
import textwrap

import ifslab
from conftest import without_seconds

RUN = dict(maps=3, size=48, iterations=60, checkpoint_every=1000, init="em")

INTERRUPTED = textwrap.dedent(
    """
    import os, signal, sys
    import ifslab
    # Python leaves SIGINT ignored when it starts with it ignored (a test command run in the
    # background of a non-interactive shell): Ctrl-C's handler is put back, as a terminal has it.
    signal.signal(signal.SIGINT, signal.default_int_handler)

    def progress(event, value):
        # A real SIGINT, as Ctrl-C sends it, once a few iterations are done.
        if event == "position" and value >= 5:
            os.kill(os.getpid(), signal.SIGINT)

    try:
        ifslab.invert(sys.argv[2], output=sys.argv[1], progress=progress, **{RUN!r})
    except KeyboardInterrupt as e:
        print("KeyboardInterrupt:", e)
        # A second run in this process runs to its end, not stopped at once.
        second = ifslab.invert(sys.argv[2], output=sys.argv[1] + "-second", **{RUN!r})
        print("second run finished:", second.summary["iterations"])
        sys.exit(3)
    print("finished")
    """
).replace("{RUN!r}", repr(RUN))


def python(code, *args):
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True)


def test_ctrl_c_checkpoints_and_the_run_resumes_bit_identically(tmp_path):
    target = tmp_path / "target.png"
    ifslab.save_image(ifslab.render("sierpinski", size=96, points=1_000_000), target)
    run_dir = tmp_path / "run"
    done = python(INTERRUPTED, run_dir, target)
    assert done.returncode == 3, done.stdout + done.stderr
    # (prefixed with the run it stopped in: the default keeps the best of three runs)
    assert "KeyboardInterrupt: " in done.stdout and "interrupted after iteration" in done.stdout
    assert "checkpoint is saved" in done.stdout
    assert "second run finished: 60" in done.stdout
    # The default recipe keeps the best of three whole runs, each in a folder of the run.
    assert (run_dir / "run-0" / "checkpoint.json").is_file()
    assert not (run_dir / "summary.json").is_file()

    resumed = python("import sys, ifslab; print(ifslab.invert(resume=sys.argv[1]).summary['iterations'])", run_dir)
    assert resumed.returncode == 0, resumed.stderr
    assert resumed.stdout.split()[-1] == "60"

    whole = ifslab.invert(target, output=tmp_path / "whole", **RUN)
    assert (run_dir / "code.json").read_bytes() == (whole.dir / "code.json").read_bytes()
    assert without_seconds(run_dir / "log.csv") == without_seconds(whole.dir / "log.csv")
