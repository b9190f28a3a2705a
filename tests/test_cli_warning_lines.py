"""A warning said while a progress bar is drawn is a line of its own: a folder of recordings run
with snn-fg run glued the first recording's burst warning to the end of its 'recordings' bar
("recordings: 0%| | 0/2 [00:00<?, ?rec/s]snn-fg: warning: window 0 ..."), and the bar was drawn
again below it."""

import subprocess
import sys
import warnings

from tqdm import tqdm

from snn_fg.cli.main import warnings_as_lines
from snn_fg.errors import InputWarning


def test_a_warning_during_a_progress_bar_is_a_line_of_its_own(capsys):
    with warnings_as_lines():
        bar = tqdm(total=2, desc="recordings", file=sys.stderr, disable=False)
        bar.update()
        warnings.warn("window 0 (0-85 ms): events on 100.0% of the sensor's pixels", InputWarning, stacklevel=2)
        bar.close()
    lines = capsys.readouterr().err.replace("\r", "\n").splitlines()
    said = [line for line in lines if "snn-fg: warning:" in line]
    assert said == ["snn-fg: warning: window 0 (0-85 ms): events on 100.0% of the sensor's pixels"]


def test_a_folder_runs_warnings_are_lines_of_their_own_naming_the_recording(tmp_path, capsys):
    """A job's warnings (said in a worker process, or in this one) come back with its row and are
    said by the parent, one line each, naming the recording; the summary row holds none of them."""
    from snn_fg.cli.batch import _run_all

    def command(args):  # (as snn-fg run says them: an InputWarning, and a line printed at the end)
        warnings.warn("window 0 (0-85 ms): events on 100.0% of the sensor's pixels", InputWarning, stacklevel=2)
        print("snn-fg: warning: 1 of 2 windows has events on more than 50% of the sensor's pixels", file=sys.stderr)
        (tmp_path / args.out).mkdir()

    jobs = [{"input": f"rec{k}.es", "out": str(tmp_path / f"o{k}"), "force": False} for k in range(2)]
    with warnings_as_lines():
        rows = list(_run_all(jobs, command, workers=1, scheduler=None, progress=True))
    assert [r["status"] for r in rows] == ["done", "done"] and not any("said" in r for r in rows)
    lines = capsys.readouterr().err.replace("\r", "\n").splitlines()
    said = [line for line in lines if "warning" in line]
    assert said == [
        line
        for k in (0, 1)
        for line in (
            f"snn-fg: warning: rec{k}.es: window 0 (0-85 ms): events on 100.0% of the sensor's pixels",
            f"snn-fg: warning: rec{k}.es: 1 of 2 windows has events on more than 50% of the sensor's pixels",
        )
    ]


def test_a_jobs_other_warnings_are_said_as_python_says_them_and_the_job_ends(tmp_path):
    """A warning that is not an input warning (numpy's, a library's) is shown as Python shows it and
    the job goes on: it was shown back into the list of recorded warnings being read, which grew for
    ever (run in a process of its own, so that a hang fails the test instead of holding the suite)."""
    code = (
        "import warnings\n"
        "from snn_fg.cli.batch import run_job\n"
        "def command(args):\n"
        "    warnings.warn('a library says so', UserWarning)\n"
        f"row = run_job({{'input': 'rec.es', 'out': {str(tmp_path / 'o')!r}, 'force': False}}, command)\n"
        "print(row['status'], row['said'])\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "done []"
    assert "UserWarning: a library says so" in done.stderr
